//! `.vshell` round trips, and every kind of damage is an error.

use crate::common;

use common::assert_every_flipped_byte_rejected;
use glam::{DVec3, Vec3};
use vps_voxmap::file::{load_shell, read_shell, save_shell, write_shell};
use vps_voxmap::shell::ShellMethod;
use vps_voxmap::{FileError, MassProperties, PointShell};

fn shell(n: usize) -> PointShell {
    let points = (0..n)
        .map(|i| Vec3::new(i as f32 * 0.01, -0.02, 0.5))
        .collect();
    let normals = (0..n)
        .map(|i| Vec3::new((i as f32).cos(), (i as f32).sin(), 0.0))
        .collect();
    PointShell {
        points,
        normals,
        voxel_size: 0.005,
        method: ShellMethod::ExactSurface,
        mass: MassProperties {
            volume: 1.5e-4,
            center_of_mass: DVec3::new(0.1, 0.2, -0.3),
            bounding_radius: 0.07,
        },
    }
}

fn encode(s: &PointShell) -> Vec<u8> {
    let mut bytes = Vec::new();
    write_shell(s, &mut bytes).unwrap();
    bytes
}

#[test]
fn round_trip_by_stream_and_path() {
    for n in [0, 1, 5000] {
        let s = shell(n);
        assert_eq!(read_shell(encode(&s).as_slice()).unwrap(), s);
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("part.vshell");
    save_shell(&shell(7), &path).unwrap();
    assert_eq!(load_shell(&path).unwrap(), shell(7));
    let err = load_shell(dir.path().join("nope.vshell")).unwrap_err();
    assert!(err.to_string().contains("nope.vshell"), "{err}");
}

#[test]
fn every_truncation_and_flipped_byte_is_an_error() {
    let bytes = encode(&shell(3));
    for len in 0..bytes.len() {
        assert!(read_shell(&bytes[..len]).is_err(), "cut at {len}");
    }
    assert_every_flipped_byte_rejected(&bytes, |b| read_shell(b));
}

#[test]
fn invalid_content_with_a_valid_hash_names_the_element() {
    let mut s = shell(4);
    s.normals[2] = Vec3::new(0.0, 0.0, 1.01);
    let err = read_shell(encode(&s).as_slice()).unwrap_err();
    assert!(err.to_string().contains("normals[2]"), "{err}");

    let mut s = shell(4);
    s.points[3].y = f32::INFINITY;
    let err = read_shell(encode(&s).as_slice()).unwrap_err();
    assert!(err.to_string().contains("points[3]"), "{err}");

    let mut s = shell(4);
    s.voxel_size = -1.0;
    let err = read_shell(encode(&s).as_slice()).unwrap_err();
    assert!(err.to_string().contains("voxel_size"), "{err}");
}

#[test]
fn mismatched_lengths_and_huge_counts_are_errors() {
    let mut s = shell(4);
    s.normals.pop();
    assert!(matches!(
        write_shell(&s, Vec::new()),
        Err(FileError::InvalidField { .. })
    ));

    // Count field (after magic 8, version 4, size 8, method 1, mass 40) claims 2^60 points.
    let mut bytes = encode(&shell(2))[..61 + 8].to_vec();
    bytes[61..].copy_from_slice(&(1u64 << 60).to_le_bytes());
    bytes.extend_from_slice(&[0u8; 64]);
    let err = read_shell(bytes.as_slice()).unwrap_err();
    assert!(
        matches!(err, FileError::Truncated { field: "points" }),
        "{err}"
    );
}
