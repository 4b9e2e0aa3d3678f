//! What every node of the cluster samples, and how it is shipped: [`ClusterAssets`] holds the
//! static scene's voxmap, every moving part's point shell split into classes and, in a session of
//! several parts, every part's body voxmap; their file bytes and content hashes
//! ([`AssetsIdentity`], one [`AssetFile`] each). A worker keeps received files in a cache
//! directory named by hash ([`AssetsCache`]), so it rejoins without a transfer, and fetches only
//! the files it lacks.

use crate::protocol::{AssetFile, AssetKind, AssetsIdentity, MAX_ASSET_PARTS, MAX_CLASSES};
use crate::ClusterError;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use vps_haptic::job::{body_map, JobTarget, SCENE_MAP};
use vps_haptic::{sample_mask, ClassedShell, KernelPose, PartialSums};
use vps_runtime::ClassPool;
use vps_voxmap::file::{read_shell, read_voxmap, write_shell, write_voxmap};
use vps_voxmap::{PointShell, VoxelTree};

/// Largest asset file (voxmap or shell file) a worker accepts (bytes).
pub const MAX_ASSET_FILE: u64 = 1 << 32;

/// Largest total of a session's asset files a worker accepts (bytes): it holds them all at once.
pub const MAX_ASSETS_TOTAL: u64 = 1 << 33;

/// Refuses an identity whose files a worker would not accept: one over [`MAX_ASSET_FILE`], or
/// all together over [`MAX_ASSETS_TOTAL`] (checked before any byte is received).
pub fn check_sizes(identity: &AssetsIdentity) -> Result<(), ClusterError> {
    if let Some(file) = identity.files.iter().find(|f| f.len > MAX_ASSET_FILE) {
        return Err(ClusterError::Join(format!(
            "an asset file of {} bytes exceeds the limit of {MAX_ASSET_FILE}",
            file.len
        )));
    }
    let total: u64 = identity.files.iter().map(|f| f.len).sum();
    if total > MAX_ASSETS_TOTAL {
        return Err(ClusterError::Join(format!(
            "the asset files total {total} bytes, over the limit of {MAX_ASSETS_TOTAL}"
        )));
    }
    Ok(())
}

/// Everything a cluster node needs to compute class shares of every job
/// ([`vps_haptic::job`]): the voxmaps (0 the static scene's, `1 + k` moving part `k`'s body
/// voxmap in a session of several parts), the moving parts' point shells split into classes, and
/// the identity (content hashes and sizes) by which the coordinator and its workers agree they
/// hold the same. Also keeps the file bytes sent to a worker lacking them. Immutable; shared with
/// `Arc`.
pub struct ClusterAssets {
    /// The voxmaps, by the jobs' voxmap index.
    pub maps: Vec<Arc<VoxelTree>>,
    /// The point shells, by part, each split into `identity.class_count` classes.
    pub shells: Vec<Arc<ClassedShell>>,
    /// Content hashes and sizes.
    pub identity: AssetsIdentity,
    files: Vec<Vec<u8>>,
}

/// One asset file decoded and checked against its [`AssetFile`].
pub enum AssetData {
    /// A voxmap.
    Voxmap(Box<VoxelTree>),
    /// A point shell.
    Shell(PointShell),
}

fn check_class_count(class_count: u32) -> Result<(), ClusterError> {
    if (1..=MAX_CLASSES).contains(&class_count) {
        Ok(())
    } else {
        Err(ClusterError::Config {
            field: "class_count",
            message: format!("{class_count} is outside 1..={MAX_CLASSES}"),
        })
    }
}

impl ClusterAssets {
    /// The assets of a one-part session: the scene's voxmap (shared, not copied) and the part's
    /// point shell split into `class_count` classes (1..=64: one datagram bit per class).
    /// Serialises both files once (allocates).
    pub fn new(
        map: Arc<VoxelTree>,
        shell: &PointShell,
        class_count: u32,
    ) -> Result<ClusterAssets, ClusterError> {
        Self::of_parts(map, &[shell], &[], class_count)
    }

    /// The assets of a session of `shells.len()` moving parts (1..=8): the scene's voxmap, every
    /// part's shell split into `class_count` classes and, for more than one part, every part's
    /// body voxmap (`bodies`, one per shell; empty for one part). Serialises every file once
    /// (allocates).
    pub fn of_parts(
        scene: Arc<VoxelTree>,
        shells: &[&PointShell],
        bodies: &[Arc<VoxelTree>],
        class_count: u32,
    ) -> Result<ClusterAssets, ClusterError> {
        check_class_count(class_count)?;
        let classed: Vec<(&PointShell, Arc<ClassedShell>)> = shells
            .iter()
            .map(|s| (*s, Arc::new(ClassedShell::new(s, class_count))))
            .collect();
        Self::of_classed_parts(scene, &classed, bodies)
    }

    /// [`ClusterAssets::of_parts`] for shells already split into classes (a session's own split,
    /// shared rather than built again): each shell's points (the file the workers get, who split
    /// it the same way) with its classes. Every split must have the same class count (1..=64).
    /// Serialises every file once (allocates).
    pub fn of_classed_parts(
        scene: Arc<VoxelTree>,
        shells: &[(&PointShell, Arc<ClassedShell>)],
        bodies: &[Arc<VoxelTree>],
    ) -> Result<ClusterAssets, ClusterError> {
        let class_count = shells.first().map_or(0, |(_, c)| c.class_count());
        check_class_count(class_count)?;
        if let Some((_, other)) = shells.iter().find(|(_, c)| c.class_count() != class_count) {
            return Err(ClusterError::Config {
                field: "class_count",
                message: format!(
                    "the part shells are split into {class_count} and {} classes: one class count for every part",
                    other.class_count()
                ),
            });
        }
        let parts = shells.len();
        let expected_bodies = if parts > 1 { parts } else { 0 };
        if !(1..=MAX_ASSET_PARTS).contains(&parts) || bodies.len() != expected_bodies {
            return Err(ClusterError::Config {
                field: "parts",
                message: format!(
                    "{parts} part shells and {} body voxmaps: 1..={MAX_ASSET_PARTS} parts, each with a body voxmap when there are several",
                    bodies.len()
                ),
            });
        }
        let maps: Vec<Arc<VoxelTree>> = std::iter::once(scene)
            .chain(bodies.iter().cloned())
            .collect();
        let mut files = Vec::with_capacity(maps.len() + parts);
        let mut described = Vec::with_capacity(maps.len() + parts);
        let encode_map = |map: &VoxelTree| -> Result<(Vec<u8>, AssetFile), ClusterError> {
            let mut bytes = Vec::new();
            write_voxmap(map, &mut bytes)
                .map_err(|e| ClusterError::Scene(format!("cannot encode a voxmap: {e}")))?;
            let file = AssetFile {
                kind: AssetKind::Voxmap,
                hash: map.content_hash(),
                len: bytes.len() as u64,
            };
            Ok((bytes, file))
        };
        let (bytes, file) = encode_map(&maps[0])?;
        files.push(bytes);
        described.push(file);
        for (shell, _) in shells {
            let mut bytes = Vec::new();
            write_shell(shell, &mut bytes)
                .map_err(|e| ClusterError::Scene(format!("cannot encode a shell: {e}")))?;
            described.push(AssetFile {
                kind: AssetKind::Shell,
                hash: *blake3::hash(&bytes).as_bytes(),
                len: bytes.len() as u64,
            });
            files.push(bytes);
        }
        for body in &maps[1..] {
            let (bytes, file) = encode_map(body)?;
            files.push(bytes);
            described.push(file);
        }
        Ok(ClusterAssets {
            shells: shells.iter().map(|(_, c)| c.clone()).collect(),
            maps,
            identity: AssetsIdentity {
                class_count,
                parts: parts as u8,
                files: described,
            },
            files,
        })
    }

    /// Decodes one received (or cached) file and checks it against `file`: its length, and its
    /// content hash (a voxmap's `VoxelTree::content_hash`, a shell file's BLAKE3). Blocking
    /// (decoding a large voxmap takes seconds), allocates.
    pub fn decode_file(file: &AssetFile, bytes: &[u8]) -> Result<AssetData, ClusterError> {
        let what = file.kind.name();
        if bytes.len() as u64 != file.len {
            return Err(ClusterError::Scene(format!(
                "received {} {what} bytes where the identity says {}",
                bytes.len(),
                file.len
            )));
        }
        let mismatch =
            || ClusterError::Scene(format!("received {what} does not match its content hash"));
        match file.kind {
            AssetKind::Voxmap => {
                let map = read_voxmap(bytes)
                    .map_err(|e| ClusterError::Scene(format!("received voxmap: {e}")))?;
                if map.content_hash() != file.hash {
                    return Err(mismatch());
                }
                Ok(AssetData::Voxmap(Box::new(map)))
            }
            AssetKind::Shell => {
                if *blake3::hash(bytes).as_bytes() != file.hash {
                    return Err(mismatch());
                }
                let shell = read_shell(bytes)
                    .map_err(|e| ClusterError::Scene(format!("received shell: {e}")))?;
                Ok(AssetData::Shell(shell))
            }
        }
    }

    /// Rebuilds the assets from received (or cached) file bytes, one per file of `identity`, in
    /// its order, each checked by [`ClusterAssets::decode_file`]. The files are kept as received
    /// (not encoded again), and `identity` is the assets' identity. Blocking, allocates.
    pub fn from_files(
        identity: &AssetsIdentity,
        files: Vec<Vec<u8>>,
    ) -> Result<ClusterAssets, ClusterError> {
        let decoded = identity
            .files
            .iter()
            .zip(&files)
            .map(|(file, bytes)| Self::decode_file(file, bytes))
            .collect::<Result<Vec<_>, _>>()?;
        Self::from_decoded(identity, files.into_iter().zip(decoded).collect())
    }

    /// The assets from files already decoded and checked ([`ClusterAssets::decode_file`]), one
    /// per file of `identity`, in its order: checks the identity's layout and that each file is
    /// of the kind its place needs. Allocates.
    pub fn from_decoded(
        identity: &AssetsIdentity,
        files: Vec<(Vec<u8>, AssetData)>,
    ) -> Result<ClusterAssets, ClusterError> {
        check_class_count(identity.class_count)?;
        identity
            .check()
            .map_err(|e| ClusterError::Join(format!("assets identity: {e}")))?;
        if files.len() != identity.files.len() {
            return Err(ClusterError::Scene(format!(
                "{} asset files where the identity names {}",
                files.len(),
                identity.files.len()
            )));
        }
        let (mut maps, mut shells, mut kept) = (Vec::new(), Vec::new(), Vec::new());
        for ((bytes, data), file) in files.into_iter().zip(&identity.files) {
            match (data, file.kind) {
                (AssetData::Voxmap(map), AssetKind::Voxmap) => maps.push(Arc::new(*map)),
                (AssetData::Shell(shell), AssetKind::Shell) => {
                    shells.push(Arc::new(ClassedShell::new(&shell, identity.class_count)))
                }
                _ => {
                    return Err(ClusterError::Scene(
                        "an asset file is not of the kind the identity names".into(),
                    ))
                }
            }
            kept.push(bytes);
        }
        // The identity's layout (checked above) puts the scene's voxmap first, then the
        // shells, then the bodies: the order of `maps` is the jobs' voxmap index.
        Ok(ClusterAssets {
            maps,
            shells,
            identity: identity.clone(),
            files: kept,
        })
    }

    /// The static scene's voxmap.
    pub fn scene_map(&self) -> &Arc<VoxelTree> {
        &self.maps[usize::from(SCENE_MAP)]
    }

    /// The session's first part's classed shell.
    pub fn first_shell(&self) -> &Arc<ClassedShell> {
        &self.shells[0]
    }

    /// The voxmap and shell of `target`, or `None` when these assets have no such shell or
    /// voxmap (a request naming it is malformed).
    pub fn target(&self, target: JobTarget) -> Option<(&VoxelTree, &ClassedShell)> {
        self.target_handles(target)
            .map(|(map, shell)| (&**map, &**shell))
    }

    /// [`ClusterAssets::target`] as the shared handles a class pool's threads take.
    pub fn target_handles(
        &self,
        target: JobTarget,
    ) -> Option<(&Arc<VoxelTree>, &Arc<ClassedShell>)> {
        let map = self.maps.get(usize::from(target.map))?;
        let shell = self.shells.get(usize::from(target.shell))?;
        Some((map, shell))
    }

    /// A class pool whose own target is the first job's (the first part in the scene) and which
    /// samples any target of these assets: `threads` compute threads, the caller included.
    /// Errors when these assets have no voxmap or no shell, or the pool cannot start (naming
    /// `field`, the caller's thread-count setting).
    pub fn class_pool(
        &self,
        threads: usize,
        field: &'static str,
    ) -> Result<ClassPool<VoxelTree>, ClusterError> {
        let (map, shell) =
            self.target_handles(JobTarget::FIRST)
                .ok_or_else(|| ClusterError::Config {
                    field: "assets",
                    message: "no voxmap or no shell to sample".into(),
                })?;
        ClassPool::new(map.clone(), shell.clone(), threads).map_err(|e| ClusterError::Config {
            field,
            message: format!("cannot start the compute pool: {e}"),
        })
    }

    /// Every job target these assets can sample: each part in the scene and, with several
    /// parts, each part's shell in every other part's body voxmap.
    pub fn targets(&self) -> Vec<JobTarget> {
        let parts = self.shells.len() as u8;
        let mut targets: Vec<JobTarget> = (0..parts)
            .map(|shell| JobTarget {
                shell,
                map: SCENE_MAP,
            })
            .collect();
        if parts > 1 {
            for shell in 0..parts {
                for owner in (0..parts).filter(|&o| o != shell) {
                    targets.push(JobTarget {
                        shell,
                        map: body_map(owner),
                    });
                }
            }
        }
        targets
    }

    /// The merged sums of the classes whose bits are set in `mask` of the job `target` at
    /// `pose`, on the calling thread (the reference a class pool's split must equal to the bit);
    /// zero sums for a target these assets do not have. Does not allocate; blocks until done.
    pub fn sample_mask(&self, target: JobTarget, pose: &KernelPose, mask: u64) -> PartialSums {
        match self.target(target) {
            Some((map, shell)) => sample_mask(map, shell, pose, mask),
            None => PartialSums::default(),
        }
    }

    /// File `k` of [`AssetsIdentity::files`] (`vps_voxmap::file` format); empty when there is none.
    pub fn file(&self, k: usize) -> &[u8] {
        self.files.get(k).map_or(&[], Vec::as_slice)
    }
}

/// Hex form of a hash (cache file names, logs).
pub fn hex(hash: &[u8; 32]) -> String {
    hash.iter().map(|b| format!("{b:02x}")).collect()
}

/// Where a worker keeps received asset files: `DIR/<hash>.voxmap` and `DIR/<hash>.shell`.
#[derive(Clone, Debug)]
pub struct AssetsCache {
    dir: Option<PathBuf>,
}

impl AssetsCache {
    /// A cache in `dir`; `None` caches nothing (every join transfers every file).
    pub fn new(dir: Option<PathBuf>) -> AssetsCache {
        AssetsCache { dir }
    }

    fn path(&self, file: &AssetFile) -> Option<PathBuf> {
        self.dir
            .as_ref()
            .map(|d| d.join(format!("{}.{}", hex(&file.hash), file.kind.name())))
    }

    /// The cached bytes of `file`, if present with its length (its content is checked by the
    /// caller, [`ClusterAssets::decode_file`]).
    pub fn read(&self, file: &AssetFile) -> Option<Vec<u8>> {
        let path = self.path(file)?;
        let len = std::fs::metadata(&path).ok()?.len();
        if len != file.len {
            return None;
        }
        std::fs::read(path).ok()
    }

    /// Stores `bytes` as `file` (best effort: a failure is logged, the worker goes on without a
    /// cache).
    pub fn store(&self, file: &AssetFile, bytes: &[u8]) {
        let (Some(dir), Some(path)) = (&self.dir, self.path(file)) else {
            return;
        };
        let result = std::fs::create_dir_all(dir).and_then(|()| {
            vps_files::atomic::write_atomically(&path, |w| w.write_all(bytes), |_, e| e)
        });
        if let Err(e) = result {
            tracing::warn!("cannot cache an asset file in {}: {e}", dir.display());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vps_haptic::{sample_all, KernelPose};

    /// Received files are kept byte for byte, the identity is the sender's, the sums are the
    /// sender's; a length, a file count or a class count other than the identity's is refused.
    #[test]
    fn received_files_are_kept_as_received_and_checked_against_the_identity() {
        let sent = vps_testkit::cluster::assets();
        let identity = sent.identity.clone();
        let files = || vec![sent.file(0).to_vec(), sent.file(1).to_vec()];
        let got = ClusterAssets::from_files(&identity, files()).unwrap();
        assert_eq!(got.identity, identity);
        assert_eq!((got.file(0), got.file(1)), (sent.file(0), sent.file(1)));
        let pose = KernelPose::from_state(&vps_haptic::PartState::at_rest(
            glam::DVec3::new(0.0, 0.0, 0.01),
            glam::DQuat::IDENTITY,
        ));
        assert_eq!(
            sample_all(&**got.scene_map(), got.first_shell(), &pose),
            sample_all(&**sent.scene_map(), sent.first_shell(), &pose)
        );
        let mut longer = files();
        longer[0].push(0);
        let err = ClusterAssets::from_files(&identity, longer).err().unwrap();
        assert!(err.to_string().contains("voxmap bytes"), "{err}");
        let err = ClusterAssets::from_files(&identity, files()[..1].to_vec())
            .err()
            .unwrap();
        assert!(err.to_string().contains("asset files"), "{err}");
        let none = AssetsIdentity {
            class_count: 0,
            ..identity
        };
        let err = ClusterAssets::from_files(&none, files()).err().unwrap();
        assert!(err.to_string().contains("class_count"), "{err}");
    }

    /// File sizes are checked one by one and together before any transfer.
    #[test]
    fn a_file_or_a_total_over_the_limits_is_refused() {
        use crate::protocol::{AssetFile, AssetKind};
        let file = |kind, len| AssetFile {
            kind,
            hash: [0; 32],
            len,
        };
        let of = |lens: [u64; 5]| AssetsIdentity {
            class_count: 8,
            parts: 2,
            files: vec![
                file(AssetKind::Voxmap, lens[0]),
                file(AssetKind::Shell, lens[1]),
                file(AssetKind::Shell, lens[2]),
                file(AssetKind::Voxmap, lens[3]),
                file(AssetKind::Voxmap, lens[4]),
            ],
        };
        assert!(check_sizes(&of([MAX_ASSET_FILE, 1, 1, 1, 1])).is_ok());
        let err = check_sizes(&of([MAX_ASSET_FILE + 1, 1, 1, 1, 1])).unwrap_err();
        assert!(err.to_string().contains("exceeds the limit"), "{err}");
        let err = check_sizes(&of([MAX_ASSET_FILE, MAX_ASSET_FILE, 1, 1, 1])).unwrap_err();
        assert!(err.to_string().contains("total"), "{err}");
    }

    /// Two parts: five files (scene, two shells, two bodies), every pair target, and a target
    /// the assets lack samples nothing.
    #[test]
    fn the_assets_of_two_parts_name_every_target_and_round_trip() {
        let scene = Arc::new(vps_testkit::scene::wall_tree());
        let shell = vps_testkit::shell::sphere_shell(200);
        let body = Arc::new(vps_testkit::scene::wall_tree());
        let sent =
            ClusterAssets::of_parts(scene, &[&shell, &shell], &[body.clone(), body], 8).unwrap();
        assert_eq!(sent.identity.files.len(), 5);
        assert_eq!(sent.targets().len(), 4);
        let files = (0..5).map(|k| sent.file(k).to_vec()).collect();
        let got = ClusterAssets::from_files(&sent.identity, files).unwrap();
        let pose = KernelPose::from_state(&vps_haptic::PartState::at_rest(
            glam::DVec3::new(0.0, 0.0, 0.004),
            glam::DQuat::IDENTITY,
        ));
        for target in sent.targets() {
            assert_eq!(
                got.sample_mask(target, &pose, u64::MAX),
                sent.sample_mask(target, &pose, u64::MAX)
            );
        }
        let missing = JobTarget { shell: 2, map: 0 };
        assert!(got.target(missing).is_none());
        assert_eq!(got.sample_mask(missing, &pose, 1), PartialSums::default());
        assert!(
            ClusterAssets::of_parts(sent.scene_map().clone(), &[&shell, &shell], &[], 8).is_err()
        );
    }
}
