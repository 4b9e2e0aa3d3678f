//! What every node of the cluster samples, and how it is shipped: [`ClusterAssets`] holds the
//! scene's voxmap, the part's point shell split into classes, their file bytes and content hashes
//! ([`AssetsIdentity`]). A worker keeps received files in a cache directory named by hash
//! ([`AssetsCache`]), so it rejoins without a transfer.

use crate::protocol::{AssetsIdentity, MAX_CLASSES};
use crate::ClusterError;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use vps_haptic::{
    sample_class_in, sample_mask, ClassedShell, KernelFrame, KernelPose, PartialSums,
};
use vps_voxmap::file::{read_shell, read_voxmap, write_shell, write_voxmap};
use vps_voxmap::{PointShell, VoxelTree};

/// Largest asset file (voxmap or shell file) a worker accepts (bytes).
pub const MAX_ASSET_FILE: u64 = 1 << 32;

/// Everything a cluster node needs to compute class shares: the scene's voxmap, the part's point
/// shell split into classes, and the identity (content hashes and sizes) by which the coordinator
/// and its workers agree they hold the same. Also keeps the serialised voxmap and shell files that
/// are sent to a worker lacking them. Immutable; shared with `Arc`.
pub struct ClusterAssets {
    /// The voxmap.
    pub map: Arc<VoxelTree>,
    /// The point shell split into `identity.class_count` classes.
    pub shell: Arc<ClassedShell>,
    /// Content hashes and sizes.
    pub identity: AssetsIdentity,
    voxmap_file: Vec<u8>,
    shell_file: Vec<u8>,
}

impl ClusterAssets {
    /// Builds the assets from a voxmap (shared, not copied) and a point shell split into `class_count` classes
    /// (1..=64: one datagram bit per class). Serialises both files once (allocates).
    pub fn new(
        map: Arc<VoxelTree>,
        shell: &PointShell,
        class_count: u32,
    ) -> Result<ClusterAssets, ClusterError> {
        if !(1..=MAX_CLASSES).contains(&class_count) {
            return Err(ClusterError::Config {
                field: "class_count",
                message: format!("{class_count} is outside 1..={MAX_CLASSES}"),
            });
        }
        let mut voxmap_file = Vec::new();
        write_voxmap(&map, &mut voxmap_file)
            .map_err(|e| ClusterError::Scene(format!("cannot encode the voxmap: {e}")))?;
        let mut shell_file = Vec::new();
        write_shell(shell, &mut shell_file)
            .map_err(|e| ClusterError::Scene(format!("cannot encode the shell: {e}")))?;
        let identity = AssetsIdentity {
            voxmap_hash: map.content_hash(),
            shell_hash: *blake3::hash(&shell_file).as_bytes(),
            class_count,
            voxmap_len: voxmap_file.len() as u64,
            shell_len: shell_file.len() as u64,
        };
        Ok(ClusterAssets {
            map,
            shell: Arc::new(ClassedShell::new(shell, class_count)),
            identity,
            voxmap_file,
            shell_file,
        })
    }

    /// Rebuilds the assets from received (or cached) file bytes and checks it against `identity`:
    /// the voxmap's content hash and the shell file's BLAKE3 must match, and the files' lengths
    /// and the class count be `identity`'s. The files are kept as received (not encoded again),
    /// and `identity` is the assets' identity.
    pub fn from_files(
        identity: &AssetsIdentity,
        voxmap_file: Vec<u8>,
        shell_file: Vec<u8>,
    ) -> Result<ClusterAssets, ClusterError> {
        if !(1..=MAX_CLASSES).contains(&identity.class_count) {
            return Err(ClusterError::Config {
                field: "class_count",
                message: format!("{} is outside 1..={MAX_CLASSES}", identity.class_count),
            });
        }
        if (voxmap_file.len() as u64, shell_file.len() as u64)
            != (identity.voxmap_len, identity.shell_len)
        {
            return Err(ClusterError::Scene(format!(
                "received {} voxmap and {} shell bytes where the identity says {} and {}",
                voxmap_file.len(),
                shell_file.len(),
                identity.voxmap_len,
                identity.shell_len
            )));
        }
        let map = read_voxmap(voxmap_file.as_slice())
            .map_err(|e| ClusterError::Scene(format!("received voxmap: {e}")))?;
        if map.content_hash() != identity.voxmap_hash {
            return Err(ClusterError::Scene(
                "received voxmap does not match its content hash".into(),
            ));
        }
        if *blake3::hash(&shell_file).as_bytes() != identity.shell_hash {
            return Err(ClusterError::Scene(
                "received shell does not match its content hash".into(),
            ));
        }
        let shell = read_shell(shell_file.as_slice())
            .map_err(|e| ClusterError::Scene(format!("received shell: {e}")))?;
        Ok(ClusterAssets {
            map: Arc::new(map),
            shell: Arc::new(ClassedShell::new(&shell, identity.class_count)),
            identity: *identity,
            voxmap_file,
            shell_file,
        })
    }

    /// The merged sums of the classes whose bits are set in `mask`, sampled in parallel on the
    /// current rayon pool (call inside `ThreadPool::install`). Exact: the same bits for any
    /// grouping. Does not allocate beyond rayon's own bookkeeping; blocks until done.
    pub fn sample_mask(&self, pose: &KernelPose, mask: u64) -> PartialSums {
        let frame = KernelFrame::new(&*self.map, &self.shell, pose);
        (0..MAX_CLASSES)
            .into_par_iter()
            .filter(|c| mask >> c & 1 == 1)
            .map(|c| sample_class_in(&*self.map, &self.shell, &frame, c))
            .reduce(PartialSums::default, |mut a, b| {
                a.merge(&b);
                a
            })
    }

    /// [`ClusterAssets::sample_mask`] on the calling thread alone: the same bits, no rayon
    /// hand-off (for one compute thread). Does not allocate; blocks until done.
    pub fn sample_mask_serial(&self, pose: &KernelPose, mask: u64) -> PartialSums {
        sample_mask(&*self.map, &self.shell, pose, mask)
    }

    /// The voxmap file bytes (`vps_voxmap::file` format).
    pub fn voxmap_file(&self) -> &[u8] {
        &self.voxmap_file
    }

    /// The point shell file bytes (`vps_voxmap::file` format).
    pub fn shell_file(&self) -> &[u8] {
        &self.shell_file
    }
}

/// Hex form of a hash (cache file names, logs).
pub fn hex(hash: &[u8; 32]) -> String {
    hash.iter().map(|b| format!("{b:02x}")).collect()
}

/// Where a worker keeps received voxmap and shell files: `DIR/<hash>.voxmap` and `DIR/<hash>.shell`.
#[derive(Clone, Debug)]
pub struct AssetsCache {
    dir: Option<PathBuf>,
}

impl AssetsCache {
    /// A cache in `dir`; `None` caches nothing (every join transfers the voxmap and shell files).
    pub fn new(dir: Option<PathBuf>) -> AssetsCache {
        AssetsCache { dir }
    }

    fn path(&self, hash: &[u8; 32], ext: &str) -> Option<PathBuf> {
        self.dir
            .as_ref()
            .map(|d| d.join(format!("{}.{ext}", hex(hash))))
    }

    /// The cached voxmap file for `hash`, if present (its content is checked by the caller).
    pub fn voxmap(&self, hash: &[u8; 32]) -> Option<Vec<u8>> {
        self.path(hash, "voxmap")
            .and_then(|p| std::fs::read(p).ok())
    }

    /// The cached shell file for `hash`, if present and matching its hash.
    pub fn shell(&self, hash: &[u8; 32]) -> Option<Vec<u8>> {
        let bytes = self
            .path(hash, "shell")
            .and_then(|p| std::fs::read(p).ok())?;
        (blake3::hash(&bytes).as_bytes() == hash).then_some(bytes)
    }

    /// Stores both files (best effort: a failure is logged, the worker goes on without a cache).
    pub fn store(&self, identity: &AssetsIdentity, voxmap: &[u8], shell: &[u8]) {
        let Some(dir) = &self.dir else { return };
        let result = std::fs::create_dir_all(dir).and_then(|()| {
            for (bytes, path) in [
                (voxmap, self.path(&identity.voxmap_hash, "voxmap")),
                (shell, self.path(&identity.shell_hash, "shell")),
            ] {
                if let Some(path) = path {
                    write_atomically(&path, bytes)?;
                }
            }
            Ok(())
        });
        if let Err(e) = result {
            tracing::warn!("cannot cache the scene in {}: {e}", dir.display());
        }
    }
}

fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vps_haptic::{sample_all, KernelPose};

    /// Received files are kept byte for byte, the identity is the sender's, the sums are the
    /// sender's; a length or class count other than the identity's is refused.
    #[test]
    fn received_files_are_kept_as_received_and_checked_against_the_identity() {
        let sent = vps_testkit::cluster::assets();
        let identity = sent.identity;
        let got = ClusterAssets::from_files(
            &identity,
            sent.voxmap_file().to_vec(),
            sent.shell_file().to_vec(),
        )
        .unwrap();
        assert_eq!(got.identity, identity);
        assert_eq!(got.voxmap_file(), sent.voxmap_file());
        assert_eq!(got.shell_file(), sent.shell_file());
        let pose = KernelPose::from_state(&vps_haptic::PartState::at_rest(
            glam::DVec3::new(0.0, 0.0, 0.01),
            glam::DQuat::IDENTITY,
        ));
        assert_eq!(
            sample_all(&*got.map, &got.shell, &pose),
            sample_all(&*sent.map, &sent.shell, &pose)
        );
        let mut longer = sent.voxmap_file().to_vec();
        longer.push(0);
        let err = ClusterAssets::from_files(&identity, longer, sent.shell_file().to_vec())
            .err()
            .unwrap();
        assert!(err.to_string().contains("voxmap and"), "{err}");
        let none = AssetsIdentity {
            class_count: 0,
            ..identity
        };
        let err = ClusterAssets::from_files(
            &none,
            sent.voxmap_file().to_vec(),
            sent.shell_file().to_vec(),
        )
        .err()
        .unwrap();
        assert!(err.to_string().contains("class_count"), "{err}");
    }
}
