//! Scenes of two moving parts (`[[part]]` tables named `left` and `right`) as scene-file text:
//! one builder for the tests of several parts (the scene file's schema, the binary's sessions,
//! the viewer, two bridge clients), so each test states only what its scene changes.

/// The floor of [`two_parts`]: the built-in box (0.1 m across, centred) as a 0.4 m × 0.4 m slab,
/// 5 cm thick, its top 0.275 m below the origin (far below the parts, which meet there).
pub const FLOOR: &str = "[[static]]
source = \"builtin:box\"
scale = [4.0, 4.0, 0.5]
translate = [0.0, 0.0, -0.3]
";

/// A 40 mm cube as a part's `source` and `scale` lines (the built-in box is 0.1 m across).
pub const CUBE_40MM: &str = "source = \"builtin:box\"\nscale = 0.4";

/// The `waypoints` line (no newline) of a hand approaching the origin along x on `side` (-1 the
/// left, +1 the right): from 60 mm to 15 mm from it. Two 40 mm parts held by two such hands
/// touch 5 mm before their hands' paths end.
pub fn approach(side: f64) -> String {
    format!(
        "waypoints = [[{:?}, 0.0, 0.0], [{:?}, 0.0, 0.0]]",
        0.06 * side,
        0.015 * side
    )
}

/// A scene of two moving parts over [`FLOOR`]: `left`, a [`CUBE_40MM`], then `right`, whose
/// `source` and `scale` lines are `right`. Each part's own tables (its `[part.hand]`, maybe a
/// `[part.device]`) are `tables(side)`, `side` -1.0 for the left part and 1.0 for the right;
/// `tail` (`[voxels]`, ..., or nothing) ends the text. The tables and the tail end in a newline
/// (so does the text, and more may be appended); panics where they do not.
pub fn two_parts(right: &str, tables: impl Fn(f64) -> String, tail: &str) -> String {
    let (left_tables, right_tables) = (tables(-1.0), tables(1.0));
    for text in [&left_tables, &right_tables] {
        assert!(
            text.ends_with('\n'),
            "a part's tables end in a newline: {text:?}"
        );
    }
    assert!(
        tail.is_empty() || tail.ends_with('\n'),
        "the tail ends in a newline: {tail:?}"
    );
    format!(
        "{FLOOR}\n[[part]]\nname = \"left\"\n{CUBE_40MM}\n{left_tables}\n\
         [[part]]\nname = \"right\"\n{right}\n{right_tables}{tail}"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_parts_puts_each_sides_tables_under_its_part() {
        let hand = |side| format!("[part.hand]\n{}\n", approach(side));
        let text = two_parts("source = \"builtin:sphere\"", hand, "[voxels]\n");
        let left = "[[part]]\nname = \"left\"\nsource = \"builtin:box\"\nscale = 0.4\n\
                    [part.hand]\nwaypoints = [[-0.06, 0.0, 0.0], [-0.015, 0.0, 0.0]]\n";
        let right = "[[part]]\nname = \"right\"\nsource = \"builtin:sphere\"\n\
                     [part.hand]\nwaypoints = [[0.06, 0.0, 0.0], [0.015, 0.0, 0.0]]\n";
        assert_eq!(text, format!("{FLOOR}\n{left}\n{right}[voxels]\n"));
    }

    #[test]
    #[should_panic(expected = "the tail ends in a newline")]
    fn a_tail_without_its_newline_panics() {
        two_parts(
            CUBE_40MM,
            |side| format!("[part.hand]\n{}\n", approach(side)),
            "[voxels]",
        );
    }
}
