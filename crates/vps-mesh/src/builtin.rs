//! Deterministic built-in meshes: analytic primitives (metres, centred at the origin).

mod bezier;
mod primitives;
mod teapot;

pub use bezier::{parse_bezier_patches, BezierPatches};
pub use primitives::{cuboid, cylinder, uv_sphere};
pub use teapot::{
    teapot, teapot_patches, teapot_with_resolution, TEAPOT_DEFAULT_RESOLUTION, TEAPOT_LENGTH_M,
};

#[cfg(test)]
pub(crate) mod test_support {
    //! Shared checks for built-in mesh tests.
    use std::collections::HashMap;

    use crate::TriMesh;

    /// Asserts every undirected edge is used by exactly two triangles, once in each direction
    /// (closed and consistently oriented).
    pub fn assert_closed(m: &TriMesh) {
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &directed {
            assert_eq!(n, 1, "directed edge {a}->{b} used {n} times");
            assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}-{b} is open");
        }
    }

    /// Number of directed edges used by more than one triangle: zero when adjacent triangles agree
    /// on winding and no edge is shared by more than two triangles.
    pub fn repeated_directed_edges(m: &TriMesh) -> usize {
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        directed.values().filter(|&&n| n > 1).count()
    }
}
