//! The Utah teapot (Newell 1975) from its 32 bicubic Bezier patches, scaled to the paper's 75 mm.

use super::bezier::{parse_bezier_patches, BezierPatches};
use crate::TriMesh;

/// The patch data (public domain; see the file header), embedded so no data file is needed at run
/// time.
const TEAPOT_BEZIER: &str = include_str!("../../../../assets/teapot-bezier.txt");

/// Length of the teapot from spout tip to handle, along x (m), as in McNeely et al. 1999.
pub const TEAPOT_LENGTH_M: f64 = 0.075;

/// Default tessellation: 12 × 12 quads per patch (about 9,000 triangles).
pub const TEAPOT_DEFAULT_RESOLUTION: u32 = 12;

/// The teapot's Bezier patches in the source units (about 6.5 units long).
pub fn teapot_patches() -> BezierPatches {
    parse_bezier_patches(TEAPOT_BEZIER).expect("embedded teapot data is valid (checked by tests)")
}

/// The teapot tessellated with [`TEAPOT_DEFAULT_RESOLUTION`]. See [`teapot_with_resolution`].
pub fn teapot() -> TriMesh {
    teapot_with_resolution(TEAPOT_DEFAULT_RESOLUTION)
}

/// The teapot with each patch tessellated on an `n × n` grid (`n` at least 1): z up, spout towards
/// +x, uniformly scaled about the source origin (bottom centre of the body) so that the x extent of
/// the tessellated mesh is exactly [`TEAPOT_LENGTH_M`]. The frame is the source's: the origin is not
/// moved to the centre of mass. Seam vertices are welded and collapsed-row triangles dropped;
/// triangles face outward (the source patches all face inward, so the winding is reversed when the
/// signed volume comes out negative). The surface is not watertight (spout and handle are separate
/// sheets pushed into the body), as in the original data.
pub fn teapot_with_resolution(n: u32) -> TriMesh {
    let mut mesh = teapot_patches().tessellate(n);
    if mesh.signed_volume() < 0.0 {
        mesh.flip_winding();
    }
    let b = mesh.bounds();
    let scale = TEAPOT_LENGTH_M / (b.max.x - b.min.x);
    for v in &mut mesh.vertices {
        *v *= scale;
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin::test_support::repeated_directed_edges;
    use crate::validate::validate;

    #[test]
    fn embedded_data_parses() {
        let p = teapot_patches();
        assert_eq!(p.points.len(), 290);
        assert_eq!(p.patches.len(), 32);
    }

    #[test]
    fn x_extent_is_75_mm_at_every_resolution() {
        for n in [1, 4, TEAPOT_DEFAULT_RESOLUTION, 20] {
            let b = teapot_with_resolution(n).bounds();
            assert!(
                (b.size().x - TEAPOT_LENGTH_M).abs() < 1e-15,
                "n={n}: {}",
                b.size().x
            );
            // Source proportions: 6.525 long, about 3.15 tall, so about 36 mm tall; z up from 0.
            assert!(
                b.min.z.abs() < 1e-12 && (b.max.z - 0.0362).abs() < 0.0015,
                "{b:?}"
            );
        }
    }

    #[test]
    fn default_teapot_is_valid_welded_and_consistently_outward() {
        let m = teapot();
        assert_eq!(
            m.triangle_count(),
            9120,
            "32 patches × 288, minus collapsed rows"
        );
        let (_, report) = validate(m.clone(), "builtin:teapot").unwrap();
        assert_eq!(report.degenerate_dropped, 0);
        assert_eq!(
            repeated_directed_edges(&m),
            0,
            "neighbouring triangles disagree on winding"
        );
        // Enclosed volume of the 75 mm teapot: body about 0.7 of its 4 cm × 4.7 cm × 3.6 cm box.
        let v = m.signed_volume();
        assert!(v > 2.0e-5 && v < 6.0e-5, "volume {v}");
        // Seams are welded: far fewer vertices than 32 × 13².
        assert!(
            m.vertices.len() < 32 * 13 * 13 * 9 / 10,
            "{}",
            m.vertices.len()
        );
    }

    #[test]
    fn parse_errors_name_the_line() {
        let err = parse_bezier_patches("# c\nvertices 1\n0 0 x\n").unwrap_err();
        assert!(err.starts_with("line 3:"), "{err}");
        let err =
            parse_bezier_patches("vertices 1\n0 0 0\npatches 1\n0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 1\n")
                .unwrap_err();
        assert!(
            err.starts_with("line 4:") && err.contains("index 1"),
            "{err}"
        );
        assert!(parse_bezier_patches("vertices 2\n0 0 0\n").is_err());
    }
}
