//! The renderer's input limits (bytes actually read from each kind of file), in one place: the
//! scene loader, the mesh and environment-map readers and the CLI all read them from here
//! (docs/limits.md).

/// Largest scene file read (bytes actually read): 16 MiB.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// Largest OBJ mesh file read (bytes actually read): 256 MiB.
pub const MAX_OBJ_BYTES: u64 = 256 << 20;
/// Largest environment-map image file read (bytes actually read): 256 MiB.
pub const MAX_ENVIRONMENT_BYTES: u64 = 256 << 20;
/// Largest `texels_per_uv` of a mapped material (`[texture] texels_per_uv`, [`crate::BumpMapped`],
/// [`crate::NdfMapped`]): 10¹² map cells per unit of texture coordinate. Beyond it a texture
/// coordinate's cell position outgrows what `f64` resolves to a cell (and what a cell index
/// holds), and the filter's footprints span astronomically many cells.
pub const MAX_TEXELS_PER_UV: f64 = 1e12;
/// Largest channel of a light's intensity, irradiance or radiance and of the background
/// (`[[light]]`, `[image] background`): 10¹². Far larger values overflow the image's `f32`
/// pixels to infinity once multiplied by a peaked BRDF.
pub const MAX_LIGHT_VALUE: f64 = 1e12;
