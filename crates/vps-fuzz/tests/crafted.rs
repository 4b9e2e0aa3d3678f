//! Crafted files from the robustness audit (docs/robustness.md): a valid 16 KiB map of 2^39
//! voxels loads in bounded memory, and a header lying about an arena's length is refused before
//! its array is allocated.

use vps_fuzz::seeds::uniform_vmap;
use vps_fuzz::CountingAlloc;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

#[test]
fn a_16_kib_map_of_2_pow_39_voxels_loads_in_bounded_memory() {
    let bytes = uniform_vmap([8192, 8192, 8192], 0.001, 1);
    assert!(bytes.len() < 17 * 1024, "{} bytes", bytes.len());
    let dir = std::env::temp_dir().join(format!("vps-fuzz-crafted-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("huge.vmap");
    std::fs::write(&path, &bytes).unwrap();

    let base = ALLOC.reset_peak();
    let tree = vps_voxmap::file::load_voxmap(&path).unwrap();
    let peak = ALLOC.peak() - base;
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(tree.spec().voxel_count(), 1 << 39);
    assert_eq!(tree.counts()[vps_voxmap::Voxel::Interior as usize], 1 << 39);
    // The tree is its 16 KiB of root slots plus the lookup directory (capped at 64 MiB); a dense
    // copy would be 2^39 bytes (549 GB).
    assert!(peak < 80 << 20, "loading took {peak} bytes");
    assert!(tree.dense_equivalent_bytes() >= 1 << 37);
}

#[test]
fn an_arena_count_beyond_the_file_is_refused_before_allocating() {
    let mut bytes = uniform_vmap([1024, 1024, 1024], 0.01, 2);
    // Claim 2^40 root slots (4 TiB) at the root count's offset.
    let root_count_at = 8 + 4 + 8 + 24 + 12 + 3;
    bytes[root_count_at..root_count_at + 8].copy_from_slice(&(1u64 << 40).to_le_bytes());
    let base = ALLOC.reset_peak();
    let err = vps_voxmap::file::read_voxmap_sized(bytes.as_slice(), bytes.len() as u64)
        .unwrap_err()
        .to_string();
    let peak = ALLOC.peak() - base;
    assert!(err.contains("root slots length"), "{err}");
    assert!(peak < 1 << 20, "refusing took {peak} bytes");
}

#[test]
fn a_trace_header_promising_millions_of_frames_reserves_little() {
    // The reader used to reserve min(frames, 2^24) frames up front: 2 GB for this 90-byte file.
    let text =
        r#"{"format":"vps-trace","version":1,"device":"d","period":0.001,"frames":16777216}"#;
    let base = ALLOC.reset_peak();
    let err = vps_device::trace::read_trace(text.as_bytes(), std::path::Path::new("t.trace"))
        .unwrap_err()
        .to_string();
    let peak = ALLOC.peak() - base;
    assert!(err.contains("t.trace") && err.contains("16777216"), "{err}");
    assert!(peak < 4 << 20, "reading the header took {peak} bytes");
}

/// The `vmap` target starts from a version-3 map (a distance band) as well as the 2-, 4- and
/// 8-bit maps without one, so the band's decoder and the kernel's reads of an accepted band are
/// what its mutations reach; and the `cache-entry` target from an entry whose band was not asked
/// for, which the cache refuses naming the band.
#[test]
fn the_map_seeds_include_a_distance_band() {
    let banded: Vec<_> = vps_fuzz::seeds::vmap()
        .iter()
        .filter_map(|b| {
            vps_voxmap::file::read_voxmap(&b[..])
                .unwrap()
                .distance_band()
                .cloned()
        })
        .collect();
    assert_eq!(banded.len(), 1);
    assert_eq!(banded[0].standoff_m(), 0.0025);
    assert!(banded[0].brick_count() > 0);

    let targets = vps_fuzz::all_targets();
    let cache = targets.iter().find(|t| t.name == "cache-entry").unwrap();
    let rejections: Vec<String> = vps_fuzz::seeds::cache_entry()
        .iter()
        .filter_map(|entry| (cache.run)(entry).err())
        .collect();
    assert!(
        rejections.iter().any(
            |e| e.contains("holds a distance band of stand-off 0.0025 m, but no distance band")
        ),
        "{rejections:#?}"
    );
}
