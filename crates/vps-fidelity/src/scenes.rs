//! The benchmark's scenes: static obstacles, a part, and the part's pose at a set separation.
//!
//! Each scene's exact contact follows from geometry: the obstacles are boxes (flat faces), the part
//! is a sphere, a box or a cylinder, and the pose is solved so that the smallest gap between the
//! part's mesh and the named obstacle face(s) equals the separation (negative: penetration). All
//! lengths are metres, world frame: z up, the obstacle faces through the origin.

use glam::{DQuat, DVec3};
use std::f64::consts::{FRAC_1_SQRT_2, FRAC_PI_2, FRAC_PI_4, TAU};
use vps_mesh::builtin::{cuboid, cylinder, uv_sphere};
use vps_mesh::TriMesh;

/// One of the benchmark's scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SceneKind {
    /// A sphere (radius 20 mm, 48 × 24 facets) above the plane z = 0: force +z, no torque.
    SpherePlane,
    /// A 40 × 30 × 20 mm box tilted 20° about x above the plane z = 0, one edge lowest: force +z,
    /// torque about a horizontal axis (the lever of the lowest edge).
    TiltedBox,
    /// A 30 mm cube in the corner of the floor z = 0 and the wall x = 0, the same gap to both:
    /// force along (1, 0, 1)/√2 when face-on.
    Corner,
    /// A peg (cylinder, radius 10 mm, 60 mm long, axis z, 32 facets) deep in a square hole of
    /// half-width `r + 3 s` (clearance three voxels, so the far wall's force layer never reaches
    /// it), the gap to the +x wall set: force −x.
    PegInHole,
    /// A cylinder (radius 12 mm, axis y) in a 90° V wedge (flanks z = |x|, both 45° off the voxel
    /// axes), the same gap to both flanks: force +z.
    Wedge,
}

impl SceneKind {
    /// Every scene, in table order.
    pub const ALL: [SceneKind; 5] = [
        SceneKind::SpherePlane,
        SceneKind::TiltedBox,
        SceneKind::Corner,
        SceneKind::PegInHole,
        SceneKind::Wedge,
    ];

    /// The scene's name in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::SpherePlane => "sphere-plane",
            SceneKind::TiltedBox => "tilted-box",
            SceneKind::Corner => "corner",
            SceneKind::PegInHole => "peg-in-hole",
            SceneKind::Wedge => "wedge",
        }
    }

    /// The static obstacles (closed boxes, world frame) for voxel size `s` (m; only the peg's hole
    /// depends on it).
    pub fn obstacles(self, s: f64) -> Vec<TriMesh> {
        let slab = || box_at(DVec3::new(0.06, 0.06, 0.02), DVec3::new(0.0, 0.0, -0.02));
        match self {
            SceneKind::SpherePlane | SceneKind::TiltedBox => vec![slab()],
            SceneKind::Corner => vec![
                box_at(DVec3::new(0.06, 0.06, 0.02), DVec3::new(0.04, 0.0, -0.02)),
                box_at(DVec3::new(0.02, 0.06, 0.06), DVec3::new(-0.02, 0.0, 0.04)),
            ],
            SceneKind::PegInHole => {
                let h = PEG_RADIUS + peg_clearance(s);
                let (t, depth) = (0.02, 0.08);
                let zc = -depth;
                vec![
                    box_at(
                        DVec3::new(t, h + 2.0 * t, depth),
                        DVec3::new(h + t, 0.0, zc),
                    ),
                    box_at(
                        DVec3::new(t, h + 2.0 * t, depth),
                        DVec3::new(-h - t, 0.0, zc),
                    ),
                    box_at(DVec3::new(h, t, depth), DVec3::new(0.0, h + t, zc)),
                    box_at(DVec3::new(h, t, depth), DVec3::new(0.0, -h - t, zc)),
                ]
            }
            SceneKind::Wedge => [FRAC_PI_4, -FRAC_PI_4]
                .iter()
                .map(|&angle| {
                    let mut m = box_at(DVec3::new(0.06, 0.06, 0.02), DVec3::new(0.0, 0.0, -0.02));
                    m.transform(1.0, DQuat::from_rotation_y(angle), DVec3::ZERO);
                    m
                })
                .collect(),
        }
    }

    /// The part's mesh (its own frame; the benchmark uses it relative to its centre of mass).
    pub fn part(self) -> TriMesh {
        match self {
            SceneKind::SpherePlane => uv_sphere(0.02, 48, 24),
            SceneKind::TiltedBox => cuboid(DVec3::new(0.02, 0.015, 0.01)),
            SceneKind::Corner => cuboid(DVec3::splat(0.015)),
            SceneKind::PegInHole => cylinder(PEG_RADIUS, 0.03, 32),
            SceneKind::Wedge => cylinder(0.012, 0.02, 32),
        }
    }

    /// The part's pose (centre-of-mass position, orientation) at separation `sep` (m) for voxel
    /// size `s` (m). `body` are the part's mesh vertices relative to its centre of mass; `u` in
    /// [0, 1)³ jitters the pose inside a voxel and about the axes the geometry leaves free, so that
    /// poses sample the lattice's phases.
    pub fn pose(self, body: &[DVec3], sep: f64, s: f64, u: [f64; 3]) -> (DVec3, DQuat) {
        let lowest =
            |q: DQuat, n: DVec3| body.iter().map(|v| n.dot(q * *v)).fold(f64::MAX, f64::min);
        match self {
            SceneKind::SpherePlane => {
                let q =
                    DQuat::from_scaled_axis(DVec3::new(u[0] - 0.5, u[1] - 0.5, u[2] - 0.5) * 2.0);
                let z = sep - lowest(q, DVec3::Z);
                (DVec3::new(u[0] * s, u[1] * s, z), q)
            }
            SceneKind::TiltedBox => {
                let q = DQuat::from_rotation_z(u[2] * FRAC_PI_2)
                    * DQuat::from_rotation_x(20f64.to_radians());
                let z = sep - lowest(q, DVec3::Z);
                (DVec3::new(u[0] * s, u[1] * s, z), q)
            }
            SceneKind::Corner => {
                let q = DQuat::from_rotation_y((u[2] - 0.5) * 2f64.to_radians());
                let x = sep - lowest(q, DVec3::X);
                let z = sep - lowest(q, DVec3::Z);
                (DVec3::new(x, u[1] * s, z), q)
            }
            SceneKind::PegInHole => {
                let q = DQuat::from_rotation_z(u[2] * TAU / 32.0);
                // Gap to the +x wall (face x = h): h − (x + max extent) = sep.
                let h = PEG_RADIUS + peg_clearance(s);
                let x = h - sep + lowest(q, DVec3::NEG_X);
                let y = (u[1] - 0.5) * s;
                (DVec3::new(x, y, PEG_CENTRE_Z), q)
            }
            SceneKind::Wedge => {
                let q =
                    DQuat::from_rotation_y(u[2] * TAU / 32.0) * DQuat::from_rotation_x(FRAC_PI_2);
                let left = DVec3::new(FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2);
                let right = DVec3::new(-FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2);
                // A centre on the z axis is z/√2 from each flank plane.
                let extent = lowest(q, left).min(lowest(q, right));
                let z = std::f64::consts::SQRT_2 * (sep - extent);
                (DVec3::new(0.0, (u[1] - 0.5) * s, z), q)
            }
        }
    }

    /// The analytic direction of the contact force for a face-on pose (unit vector).
    pub fn analytic_force_direction(self) -> DVec3 {
        match self {
            SceneKind::SpherePlane | SceneKind::TiltedBox | SceneKind::Wedge => DVec3::Z,
            SceneKind::Corner => DVec3::new(FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2),
            SceneKind::PegInHole => DVec3::NEG_X,
        }
    }
}

/// Height of the peg's centre (m): its top 40 mm below the hole's rim and its bottom 60 mm above
/// the walls' lower edges (the hole is 160 mm deep), so that within the reach of every swept
/// setting (3.5 s ≤ 35 mm) only the hole's side walls are near.
const PEG_CENTRE_Z: f64 = -0.07;

/// Radius of the peg (m).
const PEG_RADIUS: f64 = 0.01;

/// Clearance of the peg's hole (m): three voxels, so that at any swept separation (up to 3 s
/// from the +x wall) the far wall is at least 3 s away, beyond its force layer.
fn peg_clearance(s: f64) -> f64 {
    3.0 * s
}

/// A box of `half` extents centred at `centre` (m).
fn box_at(half: DVec3, centre: DVec3) -> TriMesh {
    let mut m = cuboid(half);
    m.transform(1.0, DQuat::IDENTITY, centre);
    m
}
