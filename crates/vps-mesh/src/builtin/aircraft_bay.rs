//! A procedural aircraft equipment bay: the cluttered static scene of McNeely et al. 1999 (about
//! 600k triangles of beams, tubes, bent pipes, wire bundles and panels), generated deterministically.
//!
//! Frame: origin at the bay's minimum corner; x is the long axis (0..3 m), y the width (0..2 m),
//! z up (0..1.5 m). The ends x = 0 and x = 3 are open. A square free channel of half-width
//! [`BAY_CORRIDOR_HALF_WIDTH_M`] runs along x through the middle ([`bay_corridor_box`]); every
//! piece of clutter stays at least [`BAY_CORRIDOR_CLEARANCE_M`] further out, so a 75 mm part can be
//! moved through the bay along [`bay_corridor`] and steered off it into contact.

use glam::{DQuat, DVec3};

use super::primitives::{cuboid, cylinder};
use super::rng::SplitMix64;
use super::sweep::{bent_pipe_path, swept_tube};
use crate::{Aabb, TriMesh};

/// Outer size of the bay (m): length x, width y, height z.
pub const BAY_SIZE_M: DVec3 = DVec3::new(3.0, 2.0, 1.5);

/// Half-width of the free square channel along x (m); the channel is 0.4 m wide and 0.4 m tall.
pub const BAY_CORRIDOR_HALF_WIDTH_M: f64 = 0.2;

/// Extra margin (m) between the channel and the nearest clutter.
pub const BAY_CORRIDOR_CLEARANCE_M: f64 = 0.1;

/// Seed of the generator; the bay is identical on every call and platform.
pub const BAY_SEED: u64 = 0x5EED_1999;

/// Centre of the channel's cross-section (m): y = 1.0, z = 0.75.
const CORRIDOR_CENTRE_YZ: (f64, f64) = (1.0, 0.75);

/// Thickness of the structural shell (panels, ribs, longerons) inside the outer walls (m).
const SHELL_M: f64 = 0.1;

/// Points along the channel's centreline every 0.1 m from x = 0.05 to 2.95 m (m), at
/// y = 1.0 m, z = 0.75 m; no geometry lies within `BAY_CORRIDOR_HALF_WIDTH_M +
/// BAY_CORRIDOR_CLEARANCE_M` of the line in y or z.
pub fn bay_corridor() -> Vec<DVec3> {
    let (y, z) = CORRIDOR_CENTRE_YZ;
    (0..30)
        .map(|i| DVec3::new(0.05 + 0.1 * f64::from(i), y, z))
        .collect()
}

/// The free channel (m): the full length of the bay, square cross-section of half-width
/// [`BAY_CORRIDOR_HALF_WIDTH_M`] around the centreline. No triangle of [`aircraft_bay`] comes
/// within [`BAY_CORRIDOR_CLEARANCE_M`] of it.
pub fn bay_corridor_box() -> Aabb {
    let (y, z) = CORRIDOR_CENTRE_YZ;
    let h = BAY_CORRIDOR_HALF_WIDTH_M;
    Aabb {
        min: DVec3::new(0.0, y - h, z - h),
        max: DVec3::new(BAY_SIZE_M.x, y + h, z + h),
    }
}

/// The aircraft bay (m, frame in the module docs): about 593k triangles, closed components that
/// may touch or interpenetrate each other, triangles facing outward. Deterministic: every call
/// returns an identical mesh. Allocates about 40 MB; setup-time only.
pub fn aircraft_bay() -> TriMesh {
    let mut rng = SplitMix64::new(BAY_SEED);
    let mut bay = TriMesh::default();
    add_structure(&mut bay);
    let zones = clutter_zones();
    add_equipment_boxes(&mut bay, &mut rng, &zones);
    add_straight_tubes(&mut bay, &mut rng, &zones);
    add_bent_pipes(&mut bay, &mut rng, &zones);
    add_wire_bundles(&mut bay, &mut rng, &zones);
    bay
}

/// Box-shaped regions (m) that hold the clutter: inside the structural shell and outside the
/// channel plus clearance. Floor, ceiling, left and right bands overlap in the corners.
fn clutter_zones() -> [Aabb; 4] {
    let c = bay_corridor_box();
    let keep_out_min = c.min - DVec3::splat(BAY_CORRIDOR_CLEARANCE_M);
    let keep_out_max = c.max + DVec3::splat(BAY_CORRIDOR_CLEARANCE_M);
    let lo = DVec3::new(0.02, SHELL_M, SHELL_M);
    let hi = BAY_SIZE_M - DVec3::new(0.02, SHELL_M, SHELL_M);
    let zone = |min: DVec3, max: DVec3| Aabb { min, max };
    [
        zone(lo, DVec3::new(hi.x, hi.y, keep_out_min.z)),
        zone(DVec3::new(lo.x, lo.y, keep_out_max.z), hi),
        zone(lo, DVec3::new(hi.x, keep_out_min.y, hi.z)),
        zone(DVec3::new(lo.x, keep_out_max.y, lo.z), hi),
    ]
}

/// An axis-aligned box from its corners (m).
fn block(min: DVec3, max: DVec3) -> TriMesh {
    let mut b = cuboid(0.5 * (max - min));
    b.transform(1.0, DQuat::IDENTITY, 0.5 * (min + max));
    b
}

/// An I-section beam along x from `x0` to `x1` (m), web in the plane y = `y`, flange width `w`,
/// height `h`, centred on (`y`, `z`).
fn i_beam_x(x0: f64, x1: f64, y: f64, z: f64, w: f64, h: f64) -> TriMesh {
    let t = 0.006; // flange and web thickness (m)
    let mut beam = block(
        DVec3::new(x0, y - 0.5 * w, z + 0.5 * h - t),
        DVec3::new(x1, y + 0.5 * w, z + 0.5 * h),
    );
    beam.append(&block(
        DVec3::new(x0, y - 0.5 * w, z - 0.5 * h),
        DVec3::new(x1, y + 0.5 * w, z - 0.5 * h + t),
    ));
    beam.append(&block(
        DVec3::new(x0, y - 0.5 * t, z - 0.5 * h + t),
        DVec3::new(x1, y + 0.5 * t, z + 0.5 * h - t),
    ));
    beam
}

/// Panels on floor, walls and ceiling, transverse ribs, and I-section longerons, all inside the
/// structural shell.
fn add_structure(bay: &mut TriMesh) {
    let s = BAY_SIZE_M;
    let t = 0.008; // panel thickness (m)
    let gap = 0.005;
    for i in 0..3 {
        let x0 = f64::from(i) + gap;
        let x1 = f64::from(i + 1) - gap;
        for j in 0..2 {
            let y0 = f64::from(j) + gap;
            let y1 = f64::from(j + 1) - gap;
            bay.append(&block(DVec3::new(x0, y0, 0.0), DVec3::new(x1, y1, t)));
            bay.append(&block(DVec3::new(x0, y0, s.z - t), DVec3::new(x1, y1, s.z)));
        }
        for (y0, y1) in [(0.0, t), (s.y - t, s.y)] {
            bay.append(&block(DVec3::new(x0, y0, t), DVec3::new(x1, y1, s.z - t)));
        }
    }
    // Ribs: rectangular frames across the bay every 0.5 m.
    let depth = 0.08;
    for k in 0..6 {
        let x = 0.25 + 0.5 * f64::from(k);
        let (x0, x1) = (x - 0.02, x + 0.02);
        bay.append(&block(
            DVec3::new(x0, t, t),
            DVec3::new(x1, s.y - t, t + depth),
        ));
        bay.append(&block(
            DVec3::new(x0, t, s.z - t - depth),
            DVec3::new(x1, s.y - t, s.z - t),
        ));
        bay.append(&block(
            DVec3::new(x0, t, t + depth),
            DVec3::new(x1, t + depth, s.z - t - depth),
        ));
        bay.append(&block(
            DVec3::new(x0, s.y - t - depth, t + depth),
            DVec3::new(x1, s.y - t, s.z - t - depth),
        ));
    }
    // Longerons: I-beams along x in the corners and at mid-height on both walls.
    let c = t + 0.5 * depth;
    for (y, z) in [
        (c, c),
        (s.y - c, c),
        (c, s.z - c),
        (s.y - c, s.z - c),
        (c, 0.5 * s.z),
        (s.y - c, 0.5 * s.z),
    ] {
        bay.append(&i_beam_x(0.0, s.x, y, z, 0.05, 0.07));
    }
}

/// A random point of `zone` shrunk by `margin` (m) on every side.
fn point_in(rng: &mut SplitMix64, zone: &Aabb, margin: f64) -> DVec3 {
    DVec3::new(
        rng.range(zone.min.x + margin, zone.max.x - margin),
        rng.range(zone.min.y + margin, zone.max.y - margin),
        rng.range(zone.min.z + margin, zone.max.z - margin),
    )
}

/// True when every point lies in `zone` shrunk by `margin`.
fn fits(points: &[DVec3], zone: &Aabb, margin: f64) -> bool {
    points.iter().all(|p| {
        p.cmpge(zone.min + DVec3::splat(margin)).all()
            && p.cmple(zone.max - DVec3::splat(margin)).all()
    })
}

/// Avionics boxes resting in the clutter zones.
fn add_equipment_boxes(bay: &mut TriMesh, rng: &mut SplitMix64, zones: &[Aabb; 4]) {
    for k in 0..40 {
        let zone = &zones[k % 4];
        let half = DVec3::new(
            rng.range(0.04, 0.15),
            rng.range(0.04, 0.12),
            rng.range(0.03, 0.1),
        );
        let centre = point_in(rng, zone, 0.0);
        let centre = centre.clamp(zone.min + half, zone.max - half);
        bay.append(&block(centre - half, centre + half));
    }
}

/// Straight hydraulic lines, mostly along x, some across the bay along y or up the walls along z.
fn add_straight_tubes(bay: &mut TriMesh, rng: &mut SplitMix64, zones: &[Aabb; 4]) {
    for k in 0..60 {
        let zone = &zones[k % 4];
        let radius = rng.range(0.004, 0.015);
        let start = point_in(rng, zone, radius);
        // Axis: x for most; the zone's other long axis for the rest.
        let axis = match (k % 3, k % 4) {
            (0, 0 | 1) => DVec3::Y,
            (0, _) => DVec3::Z,
            _ => DVec3::X,
        };
        let lo = (zone.min + DVec3::splat(radius)).dot(axis);
        let hi = (zone.max - DVec3::splat(radius)).dot(axis);
        let a = rng.range(lo, hi);
        let b = rng.range(lo, hi);
        let (a, b) = (a.min(b), a.max(b));
        if b - a < 0.1 {
            continue;
        }
        let centre = start - start.dot(axis) * axis + 0.5 * (a + b) * axis;
        let rotation = DQuat::from_rotation_arc(DVec3::Z, axis);
        bay.append(&cylinder(radius, 0.5 * (b - a), 32).transformed(1.0, rotation, centre));
    }
}

/// Pipes that run along x and turn through 90° towards another axis of their zone.
fn add_bent_pipes(bay: &mut TriMesh, rng: &mut SplitMix64, zones: &[Aabb; 4]) {
    let mut placed = 0;
    let mut attempt = 0;
    while placed < 48 && attempt < 10_000 {
        attempt += 1;
        let zone = &zones[attempt % 4];
        let radius = rng.range(0.006, 0.02);
        let bend = rng.range(3.0 * radius, 0.15);
        let start = point_in(rng, zone, radius);
        let first_dir = if rng.below(2) == 0 {
            DVec3::X
        } else {
            DVec3::NEG_X
        };
        let turn_axis = if rng.below(2) == 0 {
            DVec3::Y
        } else {
            DVec3::Z
        };
        let second_dir = if rng.below(2) == 0 {
            turn_axis
        } else {
            -turn_axis
        };
        let path = bent_pipe_path(
            start,
            first_dir,
            rng.range(0.1, 1.2),
            second_dir,
            rng.range(0.05, 0.6),
            bend,
            40,
        );
        if fits(&path, zone, radius) {
            bay.append(&swept_tube(&path, radius, 24));
            placed += 1;
        }
    }
}

/// Bundles of thin wires (1 to 3 mm radius) sagging and wandering along the length of the bay.
fn add_wire_bundles(bay: &mut TriMesh, rng: &mut SplitMix64, zones: &[Aabb; 4]) {
    let points_per_wire = 330;
    for k in 0..8 {
        let zone = &zones[k % 4];
        let wires = 10 + rng.below(6);
        let wire_radius: Vec<f64> = (0..wires).map(|_| rng.range(0.001, 0.003)).collect();
        // Wires on a spiral around the bundle axis, 7 mm apart.
        let offsets: Vec<(f64, f64)> = (0..wires)
            .map(|w| {
                let angle = 2.4 * f64::from(w);
                let r = 0.007 * f64::from(w).sqrt();
                (r * angle.cos(), r * angle.sin())
            })
            .collect();
        let bundle_radius = 0.007 * f64::from(wires).sqrt() + 0.003;
        let amp_y = rng.range(0.0, 0.06);
        let amp_z = rng.range(0.0, 0.06);
        let (freq, phase) = (rng.range(0.3, 1.5), rng.range(0.0, std::f64::consts::TAU));
        let margin = bundle_radius + amp_y.max(amp_z);
        let base = point_in(rng, zone, margin);
        let (x0, x1) = (zone.min.x + 0.01, zone.max.x - 0.01);
        let axis: Vec<DVec3> = (0..points_per_wire)
            .map(|i| {
                let x = x0 + (x1 - x0) * f64::from(i) / f64::from(points_per_wire - 1);
                let w = std::f64::consts::TAU * freq * x + phase;
                DVec3::new(
                    x,
                    base.y + amp_y * w.sin(),
                    base.z + amp_z * (0.7 * w).cos(),
                )
            })
            .collect();
        for (w, &(dy, dz)) in offsets.iter().enumerate() {
            let path: Vec<DVec3> = axis.iter().map(|p| *p + DVec3::new(0.0, dy, dz)).collect();
            let sides = if wire_radius[w] < 0.0015 { 6 } else { 8 };
            bay.append(&swept_tube(&path, wire_radius[w], sides));
        }
        // Clamps every 0.5 m.
        for c in 0..6 {
            let p = axis[(c * (points_per_wire as usize - 1)) / 5];
            let h = DVec3::new(0.008, bundle_radius, bundle_radius);
            bay.append(&block(p - h, p + h));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin::test_support::repeated_directed_edges;
    use crate::validate::validate;

    #[test]
    fn triangle_count_is_near_the_papers_593k_and_bay_is_valid() {
        let bay = aircraft_bay();
        let n = bay.triangle_count();
        assert!((550_000..=650_000).contains(&n), "{n} triangles");
        let (_, report) = validate(bay.clone(), "builtin:aircraft-bay").unwrap();
        assert_eq!(report.degenerate_dropped, 0);
        // Every component is closed and outward: no directed edge repeats, volume positive.
        assert_eq!(repeated_directed_edges(&bay), 0);
        assert!(bay.signed_volume() > 0.0);
        let b = bay.bounds();
        assert!(b.min.cmpge(DVec3::splat(-1e-12)).all(), "{b:?}");
        assert!(b.max.cmple(BAY_SIZE_M + DVec3::splat(1e-12)).all(), "{b:?}");
    }

    #[test]
    fn bay_is_deterministic() {
        assert!(aircraft_bay() == aircraft_bay());
    }

    #[test]
    fn corridor_waypoints_are_clear_of_every_triangle() {
        let bay = aircraft_bay();
        let clear = BAY_CORRIDOR_HALF_WIDTH_M + BAY_CORRIDOR_CLEARANCE_M;
        let waypoints = bay_corridor();
        let corridor = bay_corridor_box();
        for i in 0..bay.triangle_count() {
            let [a, b, c] = bay.triangle(i);
            let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
            // A triangle lies inside its bounding box, so a box clear of a waypoint's sphere
            // proves the triangle is too.
            for w in &waypoints {
                let d = (w.clamp(lo, hi) - *w).length();
                assert!(d >= clear - 1e-9, "triangle {i} is {d} m from waypoint {w}");
            }
            let overlaps_y = hi.y > corridor.min.y - 0.099 && lo.y < corridor.max.y + 0.099;
            let overlaps_z = hi.z > corridor.min.z - 0.099 && lo.z < corridor.max.z + 0.099;
            assert!(
                !(overlaps_y && overlaps_z),
                "triangle {i} intrudes on the channel"
            );
        }
    }

    #[test]
    fn thin_wires_make_up_a_large_share_of_the_bay() {
        let bay = aircraft_bay();
        // A wire facet (1 to 3 mm radius, about 9 mm long) is under 2 mm across in some axis and
        // under 2 cm overall; panels, beams, boxes and pipes have almost no such triangles.
        let thin = (0..bay.triangle_count())
            .filter(|&i| {
                let [a, b, c] = bay.triangle(i);
                let size = a.max(b).max(c) - a.min(b).min(c);
                size.min_element() < 0.002 && size.max_element() < 0.02
            })
            .count();
        assert!(thin > 100_000, "{thin} thin-wire triangles");
    }
}
