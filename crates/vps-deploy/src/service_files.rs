//! `vps coordinator --config FILE` and `vps worker --config FILE`: the settings of a long-lived
//! cluster service read from a TOML file (the documented examples: configs/coordinator.toml and
//! configs/worker.toml; deploy/systemd runs both this way).
//!
//! Every key is the name of a command-line flag (`voxel_size` for `--voxel-size`, `pins` for the
//! repeated `--pin`), an unknown key is refused naming the file and the key, and a flag given on
//! the command line overrides the file's value. A `pins` entry (and a `--pin`) may name a directory:
//! every `*.crt` in it is pinned. A relative path in a file (`cert`, `key`, `pins`, `cache`,
//! `scene`, `replay:FILE`, `haptic`, `record`, `report`) is taken from the file's own directory,
//! not from the working directory (`/` under systemd); on the command line it is the working
//! directory's, as for any flag.

use anyhow::{anyhow, bail, Context, Result};
use serde::Deserialize;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// Largest config file read (bytes): a few hundred are typical.
const MAX_FILE_BYTES: u64 = 1 << 20;

/// The keys of a worker's config file (all optional; see configs/worker.toml).
#[derive(Deserialize, Debug, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WorkerFile {
    /// `--coordinator` (IP:port; checked by [`vps_app::limits::parse_ip_port`]).
    pub coordinator: Option<String>,
    /// `--cert`.
    pub cert: Option<PathBuf>,
    /// `--key`.
    pub key: Option<PathBuf>,
    /// `--pin`, repeated.
    pub pins: Option<Vec<PathBuf>>,
    /// `--cache`.
    pub cache: Option<PathBuf>,
    /// `--threads`.
    pub threads: Option<usize>,
    /// `--exit-with-coordinator`.
    pub exit_with_coordinator: Option<bool>,
}

/// The keys of a coordinator's config file (all optional; see configs/coordinator.toml).
#[derive(Deserialize, Debug, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CoordinatorFile {
    /// `--listen` (IP:port; checked by [`vps_app::limits::parse_ip_port`]).
    pub listen: Option<String>,
    /// `--cert`.
    pub cert: Option<PathBuf>,
    /// `--key`.
    pub key: Option<PathBuf>,
    /// `--pin`, repeated.
    pub pins: Option<Vec<PathBuf>>,
    /// `--workers`.
    pub workers: Option<usize>,
    /// `--join-wait` (seconds).
    pub join_wait: Option<f64>,
    /// `--scene`.
    pub scene: Option<String>,
    /// `--no-cache`.
    pub no_cache: Option<bool>,
    /// `--device`.
    pub device: Option<String>,
    /// `--haptic`.
    pub haptic: Option<PathBuf>,
    /// `--voxel-size`: metres, or a string with a unit ("5mm").
    pub voxel_size: Option<toml::Value>,
    /// `--seconds`.
    pub seconds: Option<f64>,
    /// `--threads`.
    pub threads: Option<usize>,
    /// `--record`.
    pub record: Option<PathBuf>,
    /// `--report`.
    pub report: Option<PathBuf>,
    /// `--json`.
    pub json: Option<bool>,
    /// `--view`.
    pub view: Option<SocketAddr>,
    /// `--equal-shares`.
    pub equal_shares: Option<bool>,
    /// `--spin-us`.
    pub spin_us: Option<u64>,
    /// `--max-stale-frames`.
    pub max_stale_frames: Option<u64>,
}

/// Reads and parses `path` (at most [`MAX_FILE_BYTES`]); errors name the file, and for a bad or
/// unknown key, the key and its line.
fn load<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = vps_files::read_regular_to_string(path, MAX_FILE_BYTES)
        .with_context(|| format!("reading {}", path.display()))?;
    toml::from_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// `path` as written in the config file `config`: a relative one is taken from the file's own
/// directory.
pub fn beside(config: &Path, path: PathBuf) -> PathBuf {
    if path.is_relative() {
        config.parent().unwrap_or(Path::new("")).join(path)
    } else {
        path
    }
}

/// [`beside`] for every path of a list.
pub fn all_beside(config: &Path, paths: Option<Vec<PathBuf>>) -> Option<Vec<PathBuf>> {
    paths.map(|v| v.into_iter().map(|p| beside(config, p)).collect())
}

/// [`beside`] for `scene`: a scene file's path; `builtin:NAME` is kept.
pub fn scene_beside(config: &Path, scene: String) -> String {
    if scene.starts_with("builtin:") {
        return scene;
    }
    beside(config, PathBuf::from(scene)).display().to_string()
}

/// [`beside`] for `device`: the trace of `replay:FILE`; other devices are kept.
pub fn device_beside(config: &Path, device: String) -> String {
    match device.strip_prefix("replay:") {
        Some(trace) => format!("replay:{}", beside(config, PathBuf::from(trace)).display()),
        None => device,
    }
}

/// Reads a worker's config file.
pub fn load_worker(path: &Path) -> Result<WorkerFile> {
    load(path)
}

/// Reads a coordinator's config file.
pub fn load_coordinator(path: &Path) -> Result<CoordinatorFile> {
    load(path)
}

/// The certificates to pin: each path itself, or for a directory every `*.crt` in it (sorted);
/// a directory holding none is an error.
pub fn expand_pins(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for path in paths {
        if !path.is_dir() {
            out.push(path.clone());
            continue;
        }
        let mut found: Vec<PathBuf> = std::fs::read_dir(path)
            .with_context(|| format!("reading the pin directory {}", path.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "crt"))
            .collect();
        if found.is_empty() {
            bail!("pin directory {} holds no .crt files", path.display());
        }
        found.sort();
        out.extend(found);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pin_directory_pins_its_certificates() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["b.crt", "a.crt", "notes.txt"] {
            std::fs::write(dir.path().join(name), "").unwrap();
        }
        let pins = expand_pins(&[dir.path().to_path_buf()]).unwrap();
        assert_eq!(
            pins,
            vec![dir.path().join("a.crt"), dir.path().join("b.crt")]
        );
        let empty = tempfile::tempdir().unwrap();
        assert!(expand_pins(&[empty.path().to_path_buf()]).is_err());
    }
}
