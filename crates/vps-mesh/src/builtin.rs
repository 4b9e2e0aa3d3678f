//! Deterministic built-in meshes (metres): analytic primitives centred at the origin, the Utah
//! teapot, and the aircraft bay scene. [`by_name`] resolves the names in [`BUILTIN_NAMES`].

mod aircraft_bay;
mod bezier;
mod primitives;
pub mod rng;
mod sweep;
mod teapot;

pub use aircraft_bay::{
    aircraft_bay, bay_corridor, bay_corridor_box, BAY_CORRIDOR_CLEARANCE_M,
    BAY_CORRIDOR_HALF_WIDTH_M, BAY_SEED, BAY_SIZE_M,
};

pub use bezier::{parse_bezier_patches, BezierPatches};
use glam::DVec3;
pub use primitives::{cuboid, cuboid_between, cylinder, uv_sphere};
pub use sweep::{bent_pipe_path, swept_tube};

use crate::TriMesh;

pub use teapot::{
    teapot, teapot_patches, teapot_with_resolution, TEAPOT_DEFAULT_RESOLUTION, TEAPOT_LENGTH_M,
};

/// Names accepted by [`by_name`].
pub const BUILTIN_NAMES: &[&str] = &["teapot", "aircraft-bay", "box", "sphere", "cylinder"];

/// The built-in mesh called `name`, or `None` for an unknown name:
/// - `teapot`: [`teapot`] (75 mm long, about 9k triangles);
/// - `aircraft-bay`: [`aircraft_bay`] (3 m × 2 m × 1.5 m, about 593k triangles);
/// - `box`: a 0.1 m cube centred at the origin;
/// - `sphere`: radius 0.05 m, 48 segments × 24 rings;
/// - `cylinder`: radius 0.025 m, length 0.1 m along z, 48 segments.
///
/// Allocates; the bay takes a fraction of a second to generate.
pub fn by_name(name: &str) -> Option<TriMesh> {
    Some(match name {
        "teapot" => teapot(),
        "aircraft-bay" => aircraft_bay(),
        "box" => cuboid(DVec3::splat(0.05)),
        "sphere" => uv_sphere(0.05, 48, 24),
        "cylinder" => cylinder(0.025, 0.05, 48),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validate::validate;

    #[test]
    fn every_listed_name_resolves_to_a_valid_mesh() {
        for name in BUILTIN_NAMES.iter().filter(|&&n| n != "aircraft-bay") {
            let mesh = by_name(name).unwrap_or_else(|| panic!("{name} missing"));
            let (_, report) = validate(mesh, name).unwrap();
            assert_eq!(report.degenerate_dropped, 0, "{name}");
        }
        assert!(by_name("teapots").is_none());
        let cube = by_name("box").unwrap().bounds();
        assert_eq!(cube.size(), DVec3::splat(0.1));
    }
}

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
