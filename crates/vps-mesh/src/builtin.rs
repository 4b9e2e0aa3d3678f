//! Deterministic built-in meshes: analytic primitives (metres, centred at the origin).

mod primitives;

pub use primitives::{cuboid, cylinder, uv_sphere};

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

    /// Signed volume by the divergence theorem (m³); positive for outward-facing closed meshes.
    pub fn signed_volume(m: &TriMesh) -> f64 {
        (0..m.triangle_count())
            .map(|i| {
                let [a, b, c] = m.triangle(i);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }
}
