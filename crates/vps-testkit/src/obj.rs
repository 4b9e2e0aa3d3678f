//! Mesh files written as test input: the OBJ text of simple solids.

/// The OBJ text of the axis-aligned box `min`..`max` (file units, whatever the test reads them
/// as): 8 vertices and 6 outward quads (12 triangles once read).
pub fn box_obj(min: [f64; 3], max: [f64; 3]) -> String {
    let mut text = String::new();
    for i in 0..8 {
        let corner = |axis: usize| {
            if i >> axis & 1 == 0 {
                min[axis]
            } else {
                max[axis]
            }
        };
        text += &format!("v {} {} {}\n", corner(0), corner(1), corner(2));
    }
    text += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    text
}
