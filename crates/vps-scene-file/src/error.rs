//! Why a scene is rejected: every error names the scene file, and the dotted field when one is at
//! fault.

/// A scene file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file (or `builtin:NAME`).
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Not valid TOML (the message gives line and column).
    #[error("{path}: {message}")]
    Syntax {
        /// The file.
        path: String,
        /// The TOML parser's message.
        message: String,
    },
    /// A field is unknown, of the wrong type, or has a value outside its range.
    #[error("{path}{}: field `{field}`: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Field {
        /// The file.
        path: String,
        /// 1-based line of the field in the file, when the TOML parser places it.
        line: Option<usize>,
        /// Dotted field name, e.g. `voxels.voxel_size` or `static[1].units`.
        field: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

/// A [`SceneError::Field`].
pub fn field_error(path: &str, field: &str, message: impl Into<String>) -> SceneError {
    SceneError::Field {
        path: path.to_string(),
        line: None,
        field: field.to_string(),
        message: message.into(),
    }
}
