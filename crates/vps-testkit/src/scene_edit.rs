//! Bad variants of a good scene file's text, for the tests that every error names its field.

/// One replacement in a good scene's text, and the field the error of the result must name.
#[derive(Clone, Copy, Debug)]
pub struct SceneEdit {
    /// Text of the good scene to replace (every occurrence); it must occur in the scene.
    pub from: &'static str,
    /// What replaces it.
    pub to: &'static str,
    /// The field (or key, or word) the error of the edited scene must name.
    pub field: &'static str,
}

/// The texts of `base` with each of `replaced` applied, then of `base` followed by each tail of
/// `appended`, each beside the field its error must name. Panics when an edit's `from` is not in
/// `base` (the case would test the good scene).
pub fn bad_scenes(
    base: &str,
    replaced: &[SceneEdit],
    appended: &[(&'static str, &'static str)],
) -> Vec<(String, &'static str)> {
    let edited = replaced.iter().map(|e| {
        assert!(base.contains(e.from), "`{}` is not in the scene", e.from);
        (base.replace(e.from, e.to), e.field)
    });
    let extended = appended
        .iter()
        .map(|&(tail, field)| (format!("{base}{tail}"), field));
    edited.chain(extended).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edits_then_tails_in_order() {
        let replaced = [SceneEdit {
            from: "a = 1",
            to: "a = 2",
            field: "a",
        }];
        let got = bad_scenes("a = 1\n", &replaced, &[("b = 3\n", "b")]);
        assert_eq!(
            got,
            vec![
                ("a = 2\n".to_string(), "a"),
                ("a = 1\nb = 3\n".to_string(), "b")
            ]
        );
    }

    #[test]
    #[should_panic(expected = "`c = 1` is not in the scene")]
    fn an_edit_that_matches_nothing_panics() {
        let replaced = [SceneEdit {
            from: "c = 1",
            to: "c = 2",
            field: "c",
        }];
        bad_scenes("a = 1\n", &replaced, &[]);
    }
}
