//! Error types. Every message names the file and, for scene validation, the field
//! (`object[2].radius`, `light[0].direction`, …) and the problem.

use std::path::{Path, PathBuf};

fn ctx(file: &Option<PathBuf>) -> String {
    match file {
        Some(p) => format!("{}: ", p.display()),
        None => String::new(),
    }
}

/// `PATH: MESSAGE` for a material's error, without repeating the path when the resolver's
/// message already starts with it.
fn material_message(resolved: &Path, message: &str) -> String {
    let path = resolved.display().to_string();
    match message
        .strip_prefix(&path)
        .and_then(|m| m.strip_prefix(": "))
    {
        Some(rest) => format!("{path}: {rest}"),
        None => format!("{path}: {message}"),
    }
}

/// Why a scene could not be loaded or built.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{}: cannot read scene file: {source}", file.display())]
    Read {
        /// The scene file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The scene file is not valid TOML or does not match the schema (unknown field, wrong
    /// type, missing field); the message carries the line and column.
    #[error("{}: {message}", file.display())]
    Parse {
        /// The scene file.
        file: PathBuf,
        /// What the TOML parser reported.
        message: String,
    },
    /// A value is out of range or inconsistent.
    #[error("{}{field}: {problem}", ctx(file))]
    Invalid {
        /// The scene file, if the scene came from one.
        file: Option<PathBuf>,
        /// The field, e.g. `object[1].radius`.
        field: String,
        /// The problem, e.g. `must be > 0, got -1`.
        problem: String,
    },
    /// The material resolver failed.
    #[error(
        "{}{field}: material {}",
        ctx(file),
        material_message(resolved, message)
    )]
    Material {
        /// The scene file, if any.
        file: Option<PathBuf>,
        /// The field holding the reference, e.g. `object[0].material`.
        field: String,
        /// The material path after resolution against the scene's directory.
        resolved: PathBuf,
        /// The resolver's message.
        message: String,
    },
    /// A mesh file is missing or broken.
    #[error("{}: mesh: {message}", file.display())]
    Mesh {
        /// The OBJ file.
        file: PathBuf,
        /// The problem.
        message: String,
    },
    /// Refused before allocating: loading an input would need more memory than the budget
    /// (`meso_core::budget`); the message names the file, the estimate and the budget.
    #[error("{0}")]
    Budget(String),
    /// An environment map file is missing or broken.
    #[error("{}: environment map: {message}", file.display())]
    Environment {
        /// The image file.
        file: PathBuf,
        /// The problem.
        message: String,
    },
}

/// `Ok` if every coordinate of the vector `field` is finite, else [`SceneError::Invalid`].
/// What is wrong with an input file's path before it is read, for a message after the file's
/// name: `file not found`, `is a directory, not a file`, or why it cannot be examined. `None`
/// for a path that can be read (a regular file, or a device or FIFO, read with a limit).
pub(crate) fn input_path_problem(path: &std::path::Path) -> Option<String> {
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Some("file not found".into()),
        Err(e) => Some(format!("cannot read: {e}")),
        Ok(m) if m.is_dir() => Some("is a directory, not a file".into()),
        Ok(_) => None,
    }
}

/// A vector for messages: `[x, y, z]`, each number as [`meso_core::display::Num`] writes it
/// (exponent notation for very large and very small magnitudes).
pub(crate) fn vec3_text(v: glam::DVec3) -> String {
    use meso_core::display::Num;
    format!("[{}, {}, {}]", Num(v.x), Num(v.y), Num(v.z))
}

pub(crate) fn finite(field: &str, v: glam::DVec3) -> Result<(), SceneError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(SceneError::invalid(
            field,
            format!("must be finite, got {}", vec3_text(v)),
        ))
    }
}

impl SceneError {
    /// An [`SceneError::Invalid`] without a file (attach one with [`SceneError::in_file`]).
    #[must_use]
    pub fn invalid(field: impl Into<String>, problem: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            file: None,
            field: field.into(),
            problem: problem.into(),
        }
    }

    /// Attach the scene file to errors that do not carry one yet.
    #[must_use]
    pub fn in_file(self, path: &Path) -> SceneError {
        match self {
            SceneError::Invalid {
                file: None,
                field,
                problem,
            } => SceneError::Invalid {
                file: Some(path.to_path_buf()),
                field,
                problem,
            },
            SceneError::Material {
                file: None,
                field,
                resolved,
                message,
            } => SceneError::Material {
                file: Some(path.to_path_buf()),
                field,
                resolved,
                message,
            },
            e => e,
        }
    }
}

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// Writing the file failed (nothing is left behind).
    #[error("{}: cannot write image: {source}", file.display())]
    Write {
        /// The output file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Encoding failed.
    #[error("{}: cannot encode image: {message}", file.display())]
    Encode {
        /// The output file.
        file: PathBuf,
        /// The encoder's message.
        message: String,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A material's error names its file once, whether or not the resolver's message starts
    /// with it.
    #[test]
    fn a_material_error_names_its_file_once() {
        let e = |message: &str| SceneError::Material {
            file: Some(PathBuf::from("s.toml")),
            field: "object[0].material".into(),
            resolved: PathBuf::from("t1.toml"),
            message: message.into(),
        };
        assert_eq!(
            e("t1.toml: [ndf]: cannot read nope.png").to_string(),
            "s.toml: object[0].material: material t1.toml: [ndf]: cannot read nope.png"
        );
        assert_eq!(
            e("[ndf]: cannot read nope.png").to_string(),
            "s.toml: object[0].material: material t1.toml: [ndf]: cannot read nope.png"
        );
        // Only a whole leading path counts.
        assert_eq!(
            e("t1.tomlx: bad").to_string(),
            "s.toml: object[0].material: material t1.toml: t1.tomlx: bad"
        );
    }
}
