//! Memory follows the surface, not the empty volume; distance layers of 4- and 8-bit maps are the
//! exact Chebyshev bands on a box.

use glam::{DVec3, IVec3};
use vps_mesh::{builtin, TriMesh};
use vps_voxelize::{voxelize, voxelize_tree, VoxelizeOptions};
use vps_voxmap::{LayeredVoxel, TreeConfig, Voxel, VoxelLookup, VoxelWidth};

#[test]
fn memory_grows_with_surface_not_with_empty_volume() {
    let teapot = builtin::teapot();
    let size = teapot.bounds().size().max_element();
    // A 2 mm cube far away: the bounding box becomes about 10x larger per axis (1000x the volume).
    let mut speck = builtin::cuboid(DVec3::splat(0.001));
    let far = teapot.bounds().min + DVec3::splat(9.0 * size);
    speck.vertices.iter_mut().for_each(|v| *v += far);
    let opts = VoxelizeOptions {
        voxel_size: 0.001,
        ..VoxelizeOptions::default()
    };
    let (alone, a) =
        voxelize_tree(std::slice::from_ref(&teapot), &opts, TreeConfig::default()).unwrap();
    let (with_speck, b) = voxelize_tree(&[teapot, speck], &opts, TreeConfig::default()).unwrap();
    let volume_ratio = with_speck.spec().voxel_count() as f64 / alone.spec().voxel_count() as f64;
    assert!(volume_ratio > 500.0, "bounding volume grew {volume_ratio}x");
    let tree_ratio = with_speck.memory_bytes() as f64 / alone.memory_bytes() as f64;
    let work_ratio = b.peak_work_bytes as f64 / a.peak_work_bytes as f64;
    assert!(tree_ratio < 1.5, "tree memory grew {tree_ratio}x");
    assert!(work_ratio < 1.5, "working memory grew {work_ratio}x");
    // And the dense pipeline would need about 1.9 bytes per voxel of the big box.
    assert!(b.peak_work_bytes * 100 < with_speck.spec().voxel_count());
    // Same teapot voxels in both.
    let shift = (alone.spec().origin - with_speck.spec().origin) / 0.001;
    let shift = IVec3::new(
        shift.x.round() as i32,
        shift.y.round() as i32,
        shift.z.round() as i32,
    );
    assert_eq!(
        shift,
        IVec3::ZERO,
        "the teapot sits at the minimum corner of both grids"
    );
    let d = alone.spec().dims.map(|d| d as i32);
    for z in 0..d[2] {
        for y in (0..d[1]).step_by(3) {
            for x in 0..d[0] {
                let p = IVec3::new(x, y, z);
                assert_eq!(alone.get(p), with_speck.get(p), "{p}");
            }
        }
    }
    println!(
        "volume x{volume_ratio:.0}: tree {} -> {} B (x{tree_ratio:.3}), work {} -> {} B (x{work_ratio:.3})",
        alone.memory_bytes(),
        with_speck.memory_bytes(),
        a.peak_work_bytes,
        b.peak_work_bytes
    );
}

/// The box's 2-bit kinds and its 4- or 8-bit tree; checks every voxel's layer against the
/// Chebyshev distance to the boxes the 2-bit classification forms.
fn check_cuboid_layers(width: VoxelWidth) {
    let cube: TriMesh = builtin::cuboid(DVec3::new(0.031, 0.022, 0.017));
    let opts = VoxelizeOptions {
        voxel_size: 0.004,
        padding_voxels: 12,
        width,
        ..VoxelizeOptions::default()
    };
    let dense = voxelize(std::slice::from_ref(&cube), &opts).unwrap();
    let (tree, _) =
        voxelize_tree(std::slice::from_ref(&cube), &opts, TreeConfig::default()).unwrap();
    assert_eq!(tree.width(), width);
    let dims = dense.spec.dims.map(|d| d as i32);
    // Index boxes of the Interior and of everything non-Free in the 2-bit map.
    let bounds = |pred: &dyn Fn(Voxel) -> bool| {
        let (mut lo, mut hi) = (IVec3::splat(i32::MAX), IVec3::splat(i32::MIN));
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let p = IVec3::new(x, y, z);
                    if pred(dense.get(p)) {
                        lo = lo.min(p);
                        hi = hi.max(p);
                    }
                }
            }
        }
        (lo, hi)
    };
    let (ilo, ihi) = bounds(&|v| v == Voxel::Interior);
    let (plo, phi) = bounds(&|v| v != Voxel::Free);
    let inside = |p: IVec3, lo: IVec3, hi: IVec3| p.cmpge(lo).all() && p.cmple(hi).all();
    let (ls, lp) = (
        width.surface_layers().min(16) as i32,
        width.proximity_layers().min(16) as i32,
    );
    let mut seen_deep = false;
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let p = IVec3::new(x, y, z);
                let two = dense.get(p);
                let want = match two {
                    Voxel::Interior => {
                        assert!(inside(p, ilo, ihi), "interior is a box");
                        // Chebyshev distance to the Surface shell around the interior box.
                        let d = (p - ilo + 1).min(ihi - p + 1).min_element();
                        if d < ls {
                            (Voxel::Surface, d)
                        } else {
                            (Voxel::Interior, 0)
                        }
                    }
                    Voxel::Free => {
                        assert!(!inside(p, plo, phi), "non-Free voxels form a box");
                        let d = (plo - p).max(p - phi).max(IVec3::ZERO).max_element();
                        if d < lp {
                            (Voxel::Proximity, d)
                        } else {
                            (Voxel::Free, 0)
                        }
                    }
                    k => (k, 0),
                };
                let want = LayeredVoxel {
                    kind: want.0,
                    layer: want.1 as u8,
                };
                seen_deep |= want.layer >= 3;
                assert_eq!(tree.get_layered(p), want, "{width:?} at {p}");
                assert_eq!(VoxelLookup::get_layered(&tree, p), want);
                assert_eq!(tree.get(p), want.kind);
            }
        }
    }
    assert!(seen_deep, "the test reaches layers of 3 and more");
}

#[test]
fn four_bit_layers_are_chebyshev_bands_on_a_cuboid() {
    check_cuboid_layers(VoxelWidth::Four);
}

#[test]
fn eight_bit_layers_are_chebyshev_bands_on_a_cuboid() {
    check_cuboid_layers(VoxelWidth::Eight);
}

#[test]
fn two_bit_trees_report_layer_zero() {
    let cube = builtin::cuboid(DVec3::splat(0.02));
    let opts = VoxelizeOptions {
        voxel_size: 0.004,
        ..VoxelizeOptions::default()
    };
    let (tree, _) = voxelize_tree(&[cube], &opts, TreeConfig::default()).unwrap();
    let c = tree.spec().dims.map(|d| d as i32 / 2);
    for x in 0..tree.spec().dims[0] as i32 {
        let p = IVec3::new(x, c[1], c[2]);
        assert_eq!(tree.get_layered(p).layer, 0);
        assert_eq!(tree.get_layered(p).kind, tree.get(p));
    }
    let kinds: Vec<Voxel> = tree.layer_counts().iter().map(|(v, _)| v.kind).collect();
    assert_eq!(kinds, Voxel::ALL.to_vec());
}
