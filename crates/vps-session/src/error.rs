//! Why a scene is rejected ([`SceneError`], from `vps-scene-file`), and the text of an error
//! chain as `vps` prints it ([`error_chain_text`]).

pub use vps_scene_file::error::{field_error, SceneError};

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
