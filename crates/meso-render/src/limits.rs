//! The renderer's input limits (bytes actually read from each kind of file), in one place: the
//! scene loader, the mesh and environment-map readers and the CLI all read them from here
//! (docs/limits.md).

/// Largest scene file read (bytes actually read): 16 MiB.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// Largest OBJ mesh file read (bytes actually read): 256 MiB.
pub const MAX_OBJ_BYTES: u64 = 256 << 20;
/// Largest environment-map image file read (bytes actually read): 256 MiB.
pub const MAX_ENVIRONMENT_BYTES: u64 = 256 << 20;
