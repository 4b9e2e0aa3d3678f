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
pub(crate) fn field_error(path: &str, field: &str, message: impl Into<String>) -> SceneError {
    SceneError::Field {
        path: path.to_string(),
        line: None,
        field: field.to_string(),
        message: message.into(),
    }
}

/// The text of `err` and its causes joined by ": ", skipping a cause whose text is already there
/// (error types that print their source inside their own message would otherwise repeat it two or
/// three times). What `vps` prints for an error, and what a scene's mesh error carries.
pub fn error_chain_text(err: &anyhow::Error) -> String {
    let mut message = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if text.is_empty() || message.contains(&text) {
            continue;
        }
        if !message.is_empty() {
            message.push_str(": ");
        }
        message.push_str(&text);
    }
    message
}

#[cfg(test)]
mod tests {
    use super::error_chain_text;

    #[derive(Debug, thiserror::Error)]
    #[error("{path}: {source}")]
    struct Outer {
        path: String,
        source: std::io::Error,
    }

    #[test]
    fn the_chain_names_each_cause_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let err = anyhow::Error::new(Outer {
            path: "a.obj".into(),
            source: io,
        })
        .context("loading the scene");
        assert_eq!(
            error_chain_text(&err),
            "loading the scene: a.obj: No such file"
        );
        assert_eq!(format!("{err:#}").matches("No such file").count(), 2);
    }
}
