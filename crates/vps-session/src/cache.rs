//! The voxmap cache: a voxelized scene stored as a `.vmap` file named by the hash of everything
//! that decides its content: the placed geometry of every static object (the mesh files' content
//! after units, scale, rotation and translation), the voxel size, width, offset layers, padding,
//! workspace and tree shape, and a format version. Any change to an input gives another key, so a
//! stale file is never used; a file that cannot be read is rebuilt and rewritten.

use std::path::{Path, PathBuf};
use vps_mesh::TriMesh;
use vps_voxelize::VoxelizeOptions;
use vps_voxmap::file::{load_voxmap, save_voxmap};
use vps_voxmap::{TreeConfig, VoxelTree};

/// Bumped whenever the key's inputs or the voxelizer's output change meaning.
const CACHE_FORMAT: &str = "vps-voxmap-cache-1";

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

/// Reads the cached voxmap at `path`: `None` when there is none; a file that cannot be read or
/// decoded is reported on stderr and treated as absent (it will be rebuilt). Blocking.
pub fn read_cached(path: &Path) -> Option<VoxelTree> {
    if !path.exists() {
        return None;
    }
    match load_voxmap(path) {
        Ok(tree) => Some(tree),
        Err(err) => {
            eprintln!(
                "voxmap: cache file {} is unreadable ({err}); rebuilding it",
                path.display()
            );
            None
        }
    }
}

/// Writes `tree` to `path` atomically (a temporary file in the same directory, then a rename), so
/// a reader never sees half a file. Blocking.
pub fn write_cached(path: &Path, tree: &VoxelTree) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let written = save_voxmap(tree, &tmp)
        .map_err(|e| std::io::Error::other(e.to_string()))
        .and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
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

    #[test]
    fn a_written_voxmap_reads_back_and_garbage_reads_as_absent() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = vps_mesh::builtin::by_name("box").unwrap();
        let opts = VoxelizeOptions {
            voxel_size: 0.01,
            ..VoxelizeOptions::default()
        };
        let (tree, _) = vps_voxelize::voxelize_tree(&[mesh], &opts, TreeConfig::default()).unwrap();
        let path = cache_path(dir.path(), "k");
        assert!(read_cached(&path).is_none());
        write_cached(&path, &tree).unwrap();
        let back = read_cached(&path).unwrap();
        assert_eq!(back.memory_bytes(), tree.memory_bytes());
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temp file left"
        );
        std::fs::write(&path, b"garbage").unwrap();
        assert!(read_cached(&path).is_none());
    }
}
