//! Loader tests: round trips of small files in each format, and clean errors on bad input.

use std::path::PathBuf;

use glam::DVec3;

use super::*;

/// A unit-ish tetrahedron (m) used by every round-trip test.
const TETRA: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [0.1, 0.0, 0.0],
    [0.0, 0.1, 0.0],
    [0.0, 0.0, 0.1],
];
const TETRA_FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

fn write(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Asserts `m` has exactly the tetrahedron's triangles as sets of corner positions, in order.
fn assert_is_tetra(m: &TriMesh) {
    assert_eq!(m.triangle_count(), 4);
    for (i, f) in TETRA_FACES.iter().enumerate() {
        let got = m.triangle(i);
        for k in 0..3 {
            let want = TETRA[f[k]].map(f64::from);
            assert_eq!(got[k], DVec3::from_array(want), "triangle {i} corner {k}");
        }
    }
}

fn obj_text() -> String {
    let mut s = String::from("# tetra\no tetra\n");
    for v in TETRA {
        s += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    for f in TETRA_FACES {
        s += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    s
}

fn ascii_stl_text() -> String {
    let mut s = String::from("solid tetra\n");
    for f in TETRA_FACES {
        s += "  facet normal 0 0 0\n    outer loop\n";
        for k in f {
            let v = TETRA[k];
            s += &format!("      vertex {} {} {}\n", v[0], v[1], v[2]);
        }
        s += "    endloop\n  endfacet\n";
    }
    s + "endsolid tetra\n"
}

fn binary_stl_bytes(header: &[u8]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b[..header.len()].copy_from_slice(header);
    b.extend_from_slice(&(TETRA_FACES.len() as u32).to_le_bytes());
    for f in TETRA_FACES {
        b.extend_from_slice(&[0u8; 12]);
        for k in f {
            for c in TETRA[k] {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    b
}

fn ply_ascii_text(list_name: &str) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment tetra\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 4\nproperty list uchar int {list_name}\nend_header\n"
    );
    for v in TETRA {
        s += &format!("{} {} {}\n", v[0], v[1], v[2]);
    }
    for f in TETRA_FACES {
        s += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
    }
    s
}

fn ply_binary_bytes() -> Vec<u8> {
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\n\
        property double y\nproperty double z\nelement face 4\nproperty list uchar uint vertex_indices\n\
        end_header\n"
        .to_vec();
    for v in TETRA {
        for c in v {
            b.extend_from_slice(&f64::from(c).to_le_bytes());
        }
    }
    for f in TETRA_FACES {
        b.push(3);
        for k in f {
            b.extend_from_slice(&(k as u32).to_le_bytes());
        }
    }
    b
}

#[test]
fn obj_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let loaded = load_mesh(&write(&dir, "t.obj", obj_text().as_bytes())).unwrap();
    assert_is_tetra(&loaded.mesh);
    assert_eq!(loaded.report.triangle_count, 4);
}

#[test]
fn obj_quads_are_triangulated_and_extension_is_case_insensitive() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    let loaded = load_mesh(&write(&dir, "quad.OBJ", text.as_bytes())).unwrap();
    assert_eq!(loaded.mesh.triangle_count(), 2);
    assert!((loaded.mesh.area() - 1.0).abs() < 1e-12);
}

#[test]
fn ascii_stl_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let loaded = load_mesh(&write(&dir, "t.stl", ascii_stl_text().as_bytes())).unwrap();
    assert_is_tetra(&loaded.mesh);
    assert_eq!(loaded.mesh.vertices.len(), 4, "stl vertices are welded");
}

#[test]
fn binary_stl_round_trip_even_with_solid_header() {
    let dir = tempfile::tempdir().unwrap();
    for header in [&b"binary tetra"[..], &b"solid tetra exported as binary"[..]] {
        let loaded = load_mesh(&write(&dir, "t.stl", &binary_stl_bytes(header))).unwrap();
        assert_is_tetra(&loaded.mesh);
    }
}

#[test]
fn ply_ascii_round_trip_with_either_list_name() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["vertex_indices", "vertex_index"] {
        let loaded = load_mesh(&write(&dir, "t.ply", ply_ascii_text(name).as_bytes())).unwrap();
        assert_is_tetra(&loaded.mesh);
    }
}

#[test]
fn ply_binary_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let loaded = load_mesh(&write(&dir, "t.ply", &ply_binary_bytes())).unwrap();
    assert_is_tetra(&loaded.mesh);
}

#[test]
fn ply_polygons_are_fan_triangulated() {
    let dir = tempfile::tempdir().unwrap();
    let text = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
                property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
                0 0 0\n1 0 0\n1 1 0\n0.5 1.5 0\n0 1 0\n5 0 1 2 3 4\n";
    let loaded = load_mesh(&write(&dir, "pent.ply", text.as_bytes())).unwrap();
    assert_eq!(loaded.mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    assert!((loaded.mesh.area() - 1.25).abs() < 1e-12);
}

#[test]
fn scale_converts_units_before_validation() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(&dir, "mm.obj", obj_text().as_bytes());
    let loaded = load_mesh_scaled(&path, 0.001).unwrap();
    let size = loaded.mesh.bounds().size();
    assert!(
        (size - DVec3::splat(1e-4)).abs().max_element() < 1e-10,
        "{size}"
    );
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let err = load_mesh_scaled(&path, bad).unwrap_err();
        assert!(matches!(err, MeshError::InvalidScale { .. }), "{err}");
    }
    // Without the scale the same file would be accepted; with a huge one it is absurd.
    let err = load_mesh_scaled(&path, 1e6).unwrap_err();
    assert!(matches!(err, MeshError::AbsurdSize { .. }), "{err}");
}

#[test]
fn unknown_extension_and_missing_file_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let err = load_mesh(&write(&dir, "part.3ds", b"x")).unwrap_err();
    assert!(matches!(&err, MeshError::UnknownFormat { extension, .. } if extension == "3ds"));
    assert!(err.to_string().contains("part.3ds"), "{err}");
    let missing = dir.path().join("missing.obj");
    let err = load_mesh(&missing).unwrap_err();
    assert!(matches!(err, MeshError::Io { .. }));
    assert!(err.to_string().contains("missing.obj"), "{err}");
}

#[test]
fn obj_parse_error_names_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 zz\nf 1 2 3\n";
    let err = load_mesh(&write(&dir, "bad.obj", text.as_bytes())).unwrap_err();
    assert!(
        matches!(err, MeshError::Parse { line: Some(3), .. }),
        "{err:?}"
    );
    assert!(
        err.to_string().starts_with(&format!(
            "{}: line 3: ",
            dir.path().join("bad.obj").display()
        )),
        "{err}"
    );
}

#[test]
fn obj_out_of_range_face_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n";
    let err = load_mesh(&write(&dir, "oob.obj", text.as_bytes())).unwrap_err();
    assert!(err.to_string().contains("oob.obj"), "{err}");
}

#[test]
fn ply_parse_error_names_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = ply_ascii_text("vertex_indices").replace("0.1 0 0\n", "0.1 oops 0\n");
    let err = load_mesh(&write(&dir, "bad.ply", text.as_bytes())).unwrap_err();
    // Header is 10 lines; the second vertex is line 12.
    assert!(
        matches!(err, MeshError::Parse { line: Some(12), .. }),
        "{err:?}"
    );
}

#[test]
fn ply_face_with_negative_index_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let text = ply_ascii_text("vertex_indices").replace("3 1 2 3\n", "3 1 -2 3\n");
    let err = load_mesh(&write(&dir, "neg.ply", text.as_bytes())).unwrap_err();
    assert!(err.to_string().contains("face 3"), "{err}");
}

#[test]
fn stl_with_wrong_length_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = binary_stl_bytes(b"binary");
    bytes[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = load_mesh(&write(&dir, "huge.stl", &bytes)).unwrap_err();
    assert!(
        err.to_string().contains("huge.stl") && err.to_string().contains("4294967295"),
        "{err}"
    );
}

/// An empty file (an interrupted export) and a binary STL cut inside its header say so, in every
/// format, instead of the parser's "failed to fill whole buffer".
#[test]
fn empty_files_and_a_cut_stl_header_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["empty.stl", "empty.obj", "empty.ply"] {
        let err = load_mesh(&write(&dir, name, b"")).unwrap_err().to_string();
        assert!(
            err.contains(name) && err.contains("the file is empty (0 bytes)"),
            "{err}"
        );
    }
    let header = &binary_stl_bytes(b"binary")[..40];
    let err = load_mesh(&write(&dir, "cut.stl", header))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("cut.stl")
            && err.contains("40 bytes: shorter than a binary STL's 84-byte header"),
        "{err}"
    );
    assert!(!err.contains("fill whole buffer"), "{err}");
}

/// OBJ index 0 (indices start at 1) names its line and says why, and a binary PLY cut short says
/// it ends early; they said "face vertex index out of bounds" (no line) and "failed to fill whole
/// buffer".
#[test]
fn obj_index_zero_and_a_truncated_binary_ply_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n";
    let err = load_mesh(&write(&dir, "zero.obj", text.as_bytes()))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("zero.obj: line 4:") && err.contains("OBJ indices start at 1"),
        "{err}"
    );
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -9\n";
    let err = load_mesh(&write(&dir, "neg.obj", text.as_bytes()))
        .unwrap_err()
        .to_string();
    assert!(err.contains("(3 vertices read so far"), "{err}");
    let bytes = ply_binary_bytes();
    let cut = &bytes[..bytes.len() - 10];
    let err = load_mesh(&write(&dir, "cut.ply", cut))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("cut.ply") && err.contains("ends before the elements its header declares"),
        "{err}"
    );
}

/// Deterministic pseudo-random bytes.
fn garbage(len: usize, seed: u64) -> Vec<u8> {
    use rand::{RngCore, SeedableRng};
    let mut bytes = vec![0u8; len];
    rand_chacha::ChaCha8Rng::seed_from_u64(seed).fill_bytes(&mut bytes);
    bytes
}

#[test]
fn truncated_and_garbage_files_error_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let samples: [(&str, Vec<u8>); 5] = [
        ("t.obj", obj_text().into_bytes()),
        ("t.stl", ascii_stl_text().into_bytes()),
        ("b.stl", binary_stl_bytes(b"binary")),
        ("t.ply", ply_ascii_text("vertex_indices").into_bytes()),
        ("b.ply", ply_binary_bytes()),
    ];
    for (name, good) in &samples {
        for cut in [0, 1, 5, good.len() / 3, good.len() / 2, good.len() - 7] {
            let path = write(&dir, name, &good[..cut]);
            // Truncation may still leave a valid (smaller) mesh; it must never panic.
            if let Err(e) = load_mesh(&path) {
                assert!(e.to_string().contains(name), "{e}");
            }
        }
        for seed in 1..20u64 {
            let mut bytes = good.clone();
            let noise = garbage(bytes.len(), seed);
            // Corrupt every 7th byte from a random offset on, keeping the header most of the time.
            let start = (seed as usize * 13) % bytes.len();
            for i in (start..bytes.len()).step_by(7) {
                bytes[i] = noise[i];
            }
            let path = write(&dir, name, &bytes);
            if let Err(e) = load_mesh(&path) {
                assert!(e.to_string().contains(name), "{e}");
            }
            let path = write(&dir, name, &garbage(200 + seed as usize * 50, seed));
            let e = load_mesh(&path).expect_err("pure garbage must not load");
            assert!(e.to_string().contains(name), "{e}");
        }
    }
}

/// Regression inputs found by the robustness suite (`vps-fuzz`): each made a parser crate panic
/// (ply-rs-bw unwraps a u64 parse of header numbers; tobj's texture-index arithmetic overflows).
/// They must be clean errors naming the line, not caught panics.
#[test]
fn numbers_that_broke_the_parser_crates_are_errors_naming_the_line() {
    let cases: [(&[u8], MeshFormat, &str, usize); 5] = [
        (
            b"ply\nformat ascii 1.0\nelement vertex 99999999999999999999\nproperty float x\nend_header\n",
            MeshFormat::Ply,
            "t.ply",
            3,
        ),
        (
            b"ply\nformat ascii 18446744073709551616.0\nend_header\n",
            MeshFormat::Ply,
            "t.ply",
            2,
        ),
        (
            b"ply\nformat ascii 1.0\nelement face 4294967295\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n",
            MeshFormat::Ply,
            "t.ply",
            3,
        ),
        (
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/9223372036854775807 2/1 3/1\n",
            MeshFormat::Obj,
            "t.obj",
            5,
        ),
        (
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/-12 3/3\n",
            MeshFormat::Obj,
            "t.obj",
            7,
        ),
    ];
    for (bytes, format, file, line) in cases {
        let err = parse_mesh(bytes, format, file).unwrap_err().to_string();
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            err.starts_with(&format!("{file}: line {line}: parse error"))
                && err.contains("out of range"),
            "{err}"
        );
    }
}

/// stl_io names no line for a bad number in an ASCII STL; the loader finds the first `vertex` or
/// `facet normal` line whose numbers are not three finite f32.
#[test]
fn ascii_stl_bad_number_names_its_line() {
    let text = ascii_stl_text();
    // Line 4 is the first facet's first vertex.
    let nan = text.replacen("vertex 0 0 0", "vertex 0 NaN 0", 1);
    let err = parse_mesh(nan.as_bytes(), MeshFormat::Stl, "t.stl")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("t.stl: line 4: parse error"), "{err}");
    let short = text.replacen("facet normal 0 0 0", "facet normal 0 0", 1);
    let err = parse_mesh(short.as_bytes(), MeshFormat::Stl, "t.stl")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("t.stl: line 2: parse error"), "{err}");
}
