//! The viewer's scene is built from the voxmap tree's leaves and tiles, never from a dense grid:
//! a tree whose grid is 2¹⁴ voxels per axis (4.4 × 10¹² voxels, 4.4 TB as one byte per voxel) but
//! holds a few Surface voxels builds its scene with a few megabytes. Peak heap use is measured by
//! a counting global allocator (this test binary only).

use glam::UVec3;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use vps_view::{SceneLimits, ViewerContent};
use vps_voxmap::{CubeSource, GridSpec, TreeConfig, Voxel, VoxelTree, VoxelWidth};

/// The system allocator, counting live and peak bytes.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        System.dealloc(p, layout)
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The counters are process-wide: the tests take turns.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Free everywhere except Surface voxels at a few scattered positions.
struct FewVoxels(Vec<UVec3>);

impl CubeSource for FewVoxels {
    fn cube(&self, origin: UVec3, extent: u32, out: &mut [u8]) -> Option<u8> {
        let inside = |v: &UVec3| (0..3).all(|a| v[a] >= origin[a] && v[a] < origin[a] + extent);
        if !self.0.iter().any(inside) {
            return Some(Voxel::Free as u8);
        }
        out.fill(Voxel::Free as u8);
        for v in self.0.iter().filter(|v| inside(v)) {
            let l = *v - origin;
            let e = extent as usize;
            out[l.x as usize + e * (l.y as usize + e * l.z as usize)] = Voxel::Surface as u8;
        }
        None
    }
}

#[test]
fn a_huge_nearly_empty_grid_builds_its_scene_in_small_memory() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    const N: u32 = 1 << 14;
    let spec = GridSpec::at_origin(0.001, [N; 3]);
    let voxels = vec![
        UVec3::new(0, 0, 0),
        UVec3::new(1, 0, 0),
        UVec3::new(5000, 7000, 9000),
        UVec3::new(N - 1, N - 1, N - 1),
    ];
    // Lower nodes of 256³ voxels: 64³ cubes to visit while building.
    let config = TreeConfig {
        log2_dims: [3, 5, 5],
    };
    let tree = VoxelTree::from_source(spec, VoxelWidth::Two, config, &FewVoxels(voxels)).unwrap();
    let tree = Arc::new(tree);
    assert_eq!(tree.counts()[Voxel::Surface as usize], 4);

    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let scene = ViewerContent::new("huge", tree.clone(), None, SceneLimits::default());
    let peak = PEAK.load(Ordering::Relaxed) - before;

    assert_eq!(scene.meta.surface_voxels, 4);
    assert_eq!((scene.meta.coarsening, scene.boxes.len()), (1, 4));
    let far = scene.boxes.last().unwrap();
    assert!((far.x - (N as f32 - 0.5) * 0.001).abs() < 1e-4, "{far}");
    eprintln!(
        "scene of a {N}³ grid ({} TB as one byte per voxel): peak {peak} bytes",
        spec.voxel_count() / 1_000_000_000_000
    );
    assert!(
        peak < 1 << 20,
        "peak heap while building the scene: {peak} bytes"
    );
}

#[test]
fn a_huge_grid_full_of_surface_tiles_is_decimated_in_bounded_memory() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // Every voxel Surface (one tile per root cell): 4.4 × 10¹² Surface voxels, never enumerated.
    struct AllSurface;
    impl CubeSource for AllSurface {
        fn cube(&self, _: UVec3, _: u32, _: &mut [u8]) -> Option<u8> {
            Some(Voxel::Surface as u8)
        }
    }
    const N: u32 = 1 << 14;
    let spec = GridSpec::at_origin(0.001, [N; 3]);
    let config = TreeConfig {
        log2_dims: [3, 5, 5],
    };
    let tree =
        Arc::new(VoxelTree::from_source(spec, VoxelWidth::Two, config, &AllSurface).unwrap());
    let limits = SceneLimits {
        max_boxes: 20_000,
        max_shell_points: 10,
        ..SceneLimits::default()
    };
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let scene = ViewerContent::new("full", tree, None, limits);
    let peak = PEAK.load(Ordering::Relaxed) - before;
    assert_eq!(scene.meta.surface_voxels, (N as u64).pow(3));
    assert!(!scene.boxes.is_empty() && scene.boxes.len() <= 20_000);
    eprintln!(
        "full 2^14 grid: k {}, {} boxes, peak {peak} bytes",
        scene.meta.coarsening,
        scene.boxes.len()
    );
    assert!(
        peak < 16 << 20,
        "peak heap while building the scene: {peak} bytes"
    );
}
