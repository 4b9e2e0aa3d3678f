//! The voxmap cache: a voxelized scene stored as a `.vmap` file named by the hash of everything
//! that decides its content: the placed geometry of every static object (the mesh files' content
//! after units, scale, rotation and translation), the voxel size, width, offset layers, padding,
//! workspace and tree shape, and a format version. Any change to an input gives another key, so a
//! stale file is never used; a file that cannot be read is rebuilt and rewritten.
//!
//! Beside each map lies its record (`KEY.vmap.record`): the key it was written for, the map's
//! content hash and its grid. A map is used only when its record names the key asked for, its
//! content hash is the recorded one, and its grid, width and tree shape are those the inputs give
//! (computed from the meshes without voxelizing); otherwise it is rebuilt, saying why. Another
//! valid `.vmap` copied over an entry is so caught (its hash or its grid differs). The record is
//! not a signature: whoever can write the cache directory can forge a record for a map of the
//! same grid, so a cache directory shared with untrusted users is not safe.

use std::path::{Path, PathBuf};
use vps_mesh::TriMesh;
use vps_voxelize::VoxelizeOptions;
use vps_voxmap::file::{load_voxmap, save_voxmap};
use vps_voxmap::{GridSpec, TreeConfig, VoxelTree, VoxelWidth};

/// Bumped whenever the key's inputs or the voxelizer's output change meaning. 2: open parts are
/// classified by winding number and workspace cuts keep the inside (docs/voxelize.md, "Open and
/// leaky meshes"), so maps cached by 1 may differ. 3: the distance band takes its signs from a
/// map with no force-layer offset (samples deep inside a 4- or 8-bit map's Surface layers were
/// stored as far outside, samples in a 2-bit map's offset rings as inside), so bands cached by 2
/// may differ.
const CACHE_FORMAT: &str = "vps-voxmap-cache-3";

/// Where cached voxmaps live, or that caching is off.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CachePolicy {
    /// Use this directory (created when missing).
    Dir(PathBuf),
    /// Always voxelize; never read or write the cache.
    Off,
}

impl CachePolicy {
    /// The default: `$VPS_CACHE_DIR`, else `$XDG_CACHE_HOME/vps`, else `~/.cache/vps`; off when
    /// none of these is set.
    pub fn from_env() -> CachePolicy {
        let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
        if let Some(dir) = var("VPS_CACHE_DIR") {
            return CachePolicy::Dir(PathBuf::from(dir));
        }
        if let Some(xdg) = var("XDG_CACHE_HOME") {
            return CachePolicy::Dir(PathBuf::from(xdg).join("vps"));
        }
        match var("HOME") {
            Some(home) => CachePolicy::Dir(PathBuf::from(home).join(".cache").join("vps")),
            None => CachePolicy::Off,
        }
    }
}

/// The cache key (hex blake3) of voxelizing `objects` with `opts` into a tree of `tree`.
/// Hashes every vertex and triangle (allocation-free; about 1 ms per 100k triangles).
pub fn cache_key(objects: &[TriMesh], opts: &VoxelizeOptions, tree: TreeConfig) -> String {
    let mut h = blake3::Hasher::new();
    h.update(CACHE_FORMAT.as_bytes());
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(&(objects.len() as u64).to_le_bytes());
    for mesh in objects {
        h.update(&(mesh.vertices.len() as u64).to_le_bytes());
        for v in &mesh.vertices {
            for c in v.to_array() {
                h.update(&c.to_bits().to_le_bytes());
            }
        }
        h.update(&(mesh.triangles.len() as u64).to_le_bytes());
        for t in &mesh.triangles {
            for i in t {
                h.update(&i.to_le_bytes());
            }
        }
    }
    h.update(&opts.voxel_size.to_bits().to_le_bytes());
    h.update(&opts.offset_layers.to_le_bytes());
    h.update(&opts.effective_padding().to_le_bytes());
    h.update(&opts.width.bits().to_le_bytes());
    match &opts.workspace {
        Some(w) => {
            h.update(&[1]);
            for c in w.min.to_array().into_iter().chain(w.max.to_array()) {
                h.update(&c.to_bits().to_le_bytes());
            }
        }
        None => {
            h.update(&[0]);
        }
    }
    h.update(&tree.log2_dims);
    h.finalize().to_hex().to_string()
}

/// The cache file of `key` in `dir`.
pub fn cache_path(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!("{key}.vmap"))
}

/// The record beside the cache file `path` (`KEY.vmap.record`): the key it was written for, the
/// content hash of the map and its grid, checked when the map is loaded.
pub fn record_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".record");
    PathBuf::from(name)
}

/// The first line of every record.
const RECORD_MAGIC: &str = "vps voxmap cache record 1";
/// The largest record read (a record is about 300 bytes).
const MAX_RECORD_BYTES: u64 = 64 * 1024;

/// What the map asked for must be: the key of its inputs, and the grid, voxel width and tree
/// shape that voxelizing those inputs gives ([`vps_voxelize::tree_grid`]), known without
/// voxelizing.
#[derive(Clone, Debug, PartialEq)]
pub struct Expected {
    /// The cache key ([`cache_key`]).
    pub key: String,
    /// The grid of the inputs.
    pub spec: GridSpec,
    /// The voxel width asked for.
    pub width: VoxelWidth,
    /// The tree shape asked for.
    pub config: TreeConfig,
    /// The stand-off (m) of the distance band the map must carry (the `distance` force model), or
    /// `None` for a map without one.
    pub standoff_m: Option<f64>,
}

/// A grid as one line of text: origin (m, every digit), voxel size (m), dims.
fn describe_grid(spec: &GridSpec) -> String {
    format!(
        "{:?} voxels of {} m at [{}, {}, {}]",
        spec.dims, spec.voxel_size, spec.origin.x, spec.origin.y, spec.origin.z
    )
}

/// The record written beside `tree` cached under `key` ([`record_path`]): the key, the content
/// hash, the grid, the width and the tree shape, one per line.
pub fn record_text(key: &str, tree: &VoxelTree) -> String {
    let spec = tree.spec();
    format!(
        "{RECORD_MAGIC}\nkey {key}\ncontent {}\ngrid {}\nwidth {}\ntree {:?}\n",
        blake3::Hash::from(tree.content_hash()).to_hex(),
        describe_grid(spec),
        tree.width().bits(),
        tree.config().log2_dims,
    )
}

/// Why a cache file is not used; printed as "voxmap: cache file PATH {reason}; rebuilding it".
fn mismatch(path: &Path, expected: &Expected, tree: &VoxelTree) -> Option<String> {
    let record_at = record_path(path);
    let text = match vps_files::read_regular_to_string(&record_at, MAX_RECORD_BYTES) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Some(format!(
                "has no record {} of what it holds (written by an older vps, or put there by \
                 hand), so it cannot be checked",
                record_at.display()
            ))
        }
        Err(e) => {
            return Some(format!(
                "has an unreadable record {} ({e})",
                record_at.display()
            ))
        }
    };
    record_mismatch(&text, &record_at.display().to_string(), expected, tree)
}

/// Decodes a cache entry from its bytes (`map`: the `.vmap` file; `record`: its record's text)
/// and checks that it is the map `expected` asks for, as [`read_cached`] does with the files:
/// the tree, or why not (a sentence naming the entry as "the cache entry"). What the fuzz target
/// `cache-entry` runs; an accepted tree always has the grid, width and tree shape expected.
pub fn check_entry(map: &[u8], record: &str, expected: &Expected) -> Result<VoxelTree, String> {
    let tree = vps_voxmap::file::read_voxmap_sized(map, map.len() as u64)
        .map_err(|e| format!("the cache entry is unreadable ({e})"))?;
    match record_mismatch(record, "of the cache entry", expected, &tree) {
        None => Ok(tree),
        Some(reason) => Err(format!("the cache entry {reason}")),
    }
}

/// Why a map `tree` whose record (at `record_at`, for messages) reads `text` is not the one
/// `expected` asks for; `None` when it is.
fn record_mismatch(
    text: &str,
    record_at: &str,
    expected: &Expected,
    tree: &VoxelTree,
) -> Option<String> {
    if text.len() as u64 > MAX_RECORD_BYTES {
        return Some(format!(
            "has an unreadable record {record_at} (over 64 KiB)"
        ));
    }
    let field = |name: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix(' '))
            .map(str::to_owned)
    };
    if text.lines().next() != Some(RECORD_MAGIC) {
        return Some(format!(
            "has an unreadable record {} (not a vps cache record)",
            record_at
        ));
    }
    match field("key") {
        Some(k) if k == expected.key => {}
        Some(k) => {
            return Some(format!(
                "is recorded as the map of other inputs (key {k}, not {}): another scene's map \
                 was copied there",
                expected.key
            ))
        }
        None => return Some(format!("has an unreadable record {} (no key)", record_at)),
    }
    let hash = blake3::Hash::from(tree.content_hash()).to_hex().to_string();
    match field("content") {
        Some(h) if h == hash => {}
        Some(h) => {
            return Some(format!(
                "holds a map whose content hash {hash} is not the one recorded for it ({h}): the \
                 file was replaced after it was written"
            ))
        }
        None => {
            return Some(format!(
                "has an unreadable record {} (no content hash)",
                record_at
            ))
        }
    }
    // Checked from the inputs, not the record: a record forged to match another map still cannot
    // make its grid the one these inputs give.
    if *tree.spec() != expected.spec {
        return Some(format!(
            "holds a grid of {}, but these inputs give {}",
            describe_grid(tree.spec()),
            describe_grid(&expected.spec)
        ));
    }
    if tree.width() != expected.width || tree.config() != expected.config {
        return Some(format!(
            "holds {}-bit voxels in a tree of {:?}, but {}-bit in {:?} were asked for",
            tree.width().bits(),
            tree.config().log2_dims,
            expected.width.bits(),
            expected.config.log2_dims
        ));
    }
    let standoff = tree.distance_band().map(|band| band.standoff_m());
    if standoff != expected.standoff_m {
        let describe = |s: Option<f64>| match s {
            Some(s) => format!("a distance band of stand-off {s} m"),
            None => "no distance band".to_string(),
        };
        return Some(format!(
            "holds {}, but {} was asked for",
            describe(standoff),
            describe(expected.standoff_m)
        ));
    }
    None
}

/// Reads the cached voxmap at `path`: `None` when there is none, and when the file is not the map
/// `expected` asks for: a file that cannot be read or decoded, one without its record, one whose
/// record names another key or another content hash, or whose grid, width, tree shape or distance
/// band differs from what these inputs give. Each of those is reported on stderr with the reason and treated as
/// absent (it will be rebuilt and rewritten). Blocking.
pub fn read_cached(path: &Path, expected: &Expected) -> Option<VoxelTree> {
    if !path.exists() {
        return None;
    }
    match load_voxmap(path) {
        Ok(tree) => match mismatch(path, expected, &tree) {
            None => Some(tree),
            Some(reason) => {
                eprintln!(
                    "voxmap: cache file {} {reason}; not using it, rebuilding it",
                    path.display()
                );
                None
            }
        },
        Err(err) => {
            eprintln!(
                "voxmap: cache file {} is unreadable ({err}); rebuilding it",
                path.display()
            );
            None
        }
    }
}

/// Writes `tree` to `path` and its record (the key `key`, content hash, grid) beside it
/// ([`record_path`]), each atomically (a temporary file in the same directory, then a rename), so
/// a reader never sees half a file; the map is written first, so a map whose record is missing or
/// stale is refused, never trusted. A cache "directory" that exists but is not a directory is an
/// error saying so. Blocking.
pub fn write_cached(path: &Path, key: &str, tree: &VoxelTree) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    if dir.exists() && !dir.is_dir() {
        return Err(std::io::Error::other(format!(
            "the cache directory {} is not a directory; set VPS_CACHE_DIR to a directory, or \
             give --no-cache",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir)?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let record_tmp = dir.join(format!(".{name}.record.{}.tmp", std::process::id()));
    let written = save_voxmap(tree, &tmp)
        .map_err(|e| std::io::Error::other(e.to_string()))
        .and_then(|()| std::fs::rename(&tmp, path))
        .and_then(|()| std::fs::write(&record_tmp, record_text(key, tree)))
        .and_then(|()| std::fs::rename(&record_tmp, record_path(path)));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
        let _ = std::fs::remove_file(&record_tmp);
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_key_follows_every_input() {
        let mesh = vps_mesh::builtin::by_name("box").unwrap();
        let opts = VoxelizeOptions::default();
        let tree = TreeConfig::default();
        let key = cache_key(std::slice::from_ref(&mesh), &opts, tree);
        assert_eq!(key, cache_key(std::slice::from_ref(&mesh), &opts, tree));
        let mut moved = mesh.clone();
        moved.vertices[0].x += 1e-9;
        assert_ne!(key, cache_key(&[moved], &opts, tree));
        let finer = VoxelizeOptions {
            voxel_size: 0.004,
            ..opts
        };
        assert_ne!(key, cache_key(std::slice::from_ref(&mesh), &finer, tree));
        let deeper = VoxelizeOptions {
            offset_layers: 3,
            ..opts
        };
        assert_ne!(key, cache_key(std::slice::from_ref(&mesh), &deeper, tree));
        assert_ne!(
            key,
            cache_key(std::slice::from_ref(&mesh), &opts, TreeConfig::uniform(2))
        );
    }

    /// A cache entry of the box at 1 cm, with what it must be.
    fn entry(dir: &Path, voxel_size: f64) -> (PathBuf, Expected, VoxelTree) {
        let mesh = vps_mesh::builtin::by_name("box").unwrap();
        let opts = VoxelizeOptions {
            voxel_size,
            ..VoxelizeOptions::default()
        };
        let objects = std::slice::from_ref(&mesh);
        let (tree, _) = vps_voxelize::voxelize_tree(objects, &opts, TreeConfig::default()).unwrap();
        let key = cache_key(objects, &opts, TreeConfig::default());
        let expected = Expected {
            spec: vps_voxelize::tree_grid(objects, &opts).unwrap(),
            width: opts.width,
            config: TreeConfig::default(),
            key: key.clone(),
            standoff_m: None,
        };
        (cache_path(dir, &key), expected, tree)
    }

    #[test]
    fn a_written_voxmap_reads_back_and_garbage_reads_as_absent() {
        let dir = tempfile::tempdir().unwrap();
        let (path, expected, tree) = entry(dir.path(), 0.01);
        assert_eq!(*tree.spec(), expected.spec, "tree_grid is the grid built");
        assert!(read_cached(&path, &expected).is_none());
        write_cached(&path, &expected.key, &tree).unwrap();
        let back = read_cached(&path, &expected).unwrap();
        assert_eq!(back.memory_bytes(), tree.memory_bytes());
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            2,
            "the map and its record, no temp file left"
        );
        std::fs::write(&path, b"garbage").unwrap();
        assert!(read_cached(&path, &expected).is_none());
    }

    /// Another valid map over an entry (with or without its own record), a missing record, a
    /// record forged to name this key and the other map's hash: each is refused.
    #[test]
    fn another_map_in_an_entry_is_not_used() {
        let dir = tempfile::tempdir().unwrap();
        let (path, expected, tree) = entry(dir.path(), 0.01);
        let (other_path, other_expected, other) = entry(dir.path(), 0.02);
        write_cached(&path, &expected.key, &tree).unwrap();
        write_cached(&other_path, &other_expected.key, &other).unwrap();
        // The map only.
        std::fs::copy(&other_path, &path).unwrap();
        assert!(read_cached(&path, &expected).is_none());
        // The map and its record.
        std::fs::copy(record_path(&other_path), record_path(&path)).unwrap();
        assert!(read_cached(&path, &expected).is_none());
        // A record forged for this key and the other map's content.
        std::fs::write(record_path(&path), record_text(&expected.key, &other)).unwrap();
        assert!(read_cached(&path, &expected).is_none());
        // No record.
        write_cached(&path, &expected.key, &tree).unwrap();
        assert!(read_cached(&path, &expected).is_some());
        std::fs::remove_file(record_path(&path)).unwrap();
        assert!(read_cached(&path, &expected).is_none());
        let reason = mismatch(&path, &expected, &tree).unwrap();
        assert!(reason.contains("no record"), "{reason}");
        std::fs::write(record_path(&path), record_text(&expected.key, &other)).unwrap();
        let reason = mismatch(&path, &expected, &tree).unwrap();
        assert!(reason.contains("content hash"), "{reason}");
        let reason = mismatch(&path, &expected, &other).unwrap();
        assert!(reason.contains("grid of"), "{reason}");
        // The right map, but a distance band was asked for and it carries none.
        std::fs::write(record_path(&path), record_text(&expected.key, &tree)).unwrap();
        let banded = Expected {
            standoff_m: Some(0.001),
            ..expected
        };
        let reason = mismatch(&path, &banded, &tree).unwrap();
        assert!(
            reason.contains("holds no distance band, but a distance band of stand-off 0.001 m"),
            "{reason}"
        );
    }

    #[test]
    fn a_cache_directory_that_is_a_file_says_so() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("cache");
        std::fs::write(&file, b"").unwrap();
        let (_, expected, tree) = entry(dir.path(), 0.01);
        let err = write_cached(&cache_path(&file, &expected.key), &expected.key, &tree)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("is not a directory") && err.contains("VPS_CACHE_DIR"),
            "{err}"
        );
    }
}
