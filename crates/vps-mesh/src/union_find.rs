//! Union-find over vertex ids (`parent[v] == v` at a root), for grouping triangles into connected
//! pieces: [`crate::health`] and the exact reference's components use it. No allocation.

/// The root of `v`'s set, halving the path on the way. `v` must index `parent`.
pub fn find(parent: &mut [u32], mut v: u32) -> u32 {
    while parent[v as usize] != v {
        let up = parent[parent[v as usize] as usize];
        parent[v as usize] = up;
        v = up;
    }
    v
}

/// Joins the sets of `a` and `b`; the smaller root becomes the root of both.
pub fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
}
