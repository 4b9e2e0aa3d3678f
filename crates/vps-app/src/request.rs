//! What a person asks of a session, with no command-line parser in it: the scene, the overrides
//! of the scene file's settings, the session's length, threads and outputs
//! ([`SessionRequest`]). (How a coordinator gathers its workers' replies is
//! [`vps_cluster::GatherConfig`], taken as it is.)
//! The binary's `cli` module fills these from its flags; tests and benchmarks build them directly.

use std::net::SocketAddr;
use std::path::PathBuf;

/// Which scene a session runs, and whether its voxmap may come from the cache.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneRequest {
    /// A scene file (TOML) or `builtin:NAME`.
    pub scene: String,
    /// Always voxelize: neither read nor write the voxmap cache.
    pub no_cache: bool,
    /// Memory budget of the whole scene (bytes); `None`: half of physical memory.
    pub max_memory: Option<u64>,
}

impl Default for SceneRequest {
    /// The default scene ([`vps_session::DEFAULT_SCENE`]), cache on, the default budget.
    fn default() -> Self {
        SceneRequest {
            scene: vps_session::DEFAULT_SCENE.into(),
            no_cache: false,
            max_memory: None,
        }
    }
}

impl SceneRequest {
    /// How to build the scene: `voxel_size` (m) instead of the scene's when given.
    pub fn build_options(&self, voxel_size: Option<f64>) -> vps_session::BuildOptions {
        vps_session::BuildOptions {
            voxel_size,
            cache: if self.no_cache {
                vps_session::CachePolicy::Off
            } else {
                vps_session::CachePolicy::from_env()
            },
            max_memory_bytes: self.max_memory,
            ..vps_session::BuildOptions::default()
        }
    }

    /// The memory budget (bytes): `max_memory`, else half of physical memory.
    pub fn memory_budget(&self) -> u64 {
        self.max_memory
            .unwrap_or_else(vps_voxelize::default_memory_budget)
    }
}

/// Overrides of the scene file's bridge settings (`--device bridge[:ADDR]` only); `None` keeps
/// the scene's value. Ranges are checked by whoever parses them (the command line's parsers).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BridgeOverrides {
    /// Scene metres per device metre.
    pub map_scale: Option<f64>,
    /// Scene position of the device origin (m).
    pub map_offset: Option<[f64; 3]>,
    /// Rotation from device axes to scene axes, degrees about X, Y, Z (X applied first).
    pub map_rotate_deg: Option<[f64; 3]>,
    /// Device force per scene force (also scales torque).
    pub force_scale: Option<f64>,
    /// A device silent this long (ms) is held with zero output.
    pub pose_timeout_ms: Option<f64>,
    /// Write every wrench sent to the device to this file.
    pub log_wrenches: Option<PathBuf>,
}

/// One session as asked for: the scene and every override of its settings. `Default` is the
/// command line's defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionRequest {
    /// The scene.
    pub scene: SceneRequest,
    /// The device as `DeviceChoice::parse` reads it (`sim`, `bridge[:ADDR]`, `replay:FILE`, ...);
    /// `None`: the scene's.
    pub device: Option<String>,
    /// Haptic parameters (TOML file) instead of the scene's `[haptic]`.
    pub haptic: Option<PathBuf>,
    /// Voxel size (m) instead of the scene's.
    pub voxel_size: Option<f64>,
    /// Session length (s); `None`: the simulated hand's path, a replay's trace, else 30 s.
    pub seconds: Option<f64>,
    /// Compute threads, the frame thread included (0 is taken as 1).
    pub threads: usize,
    /// Frames back to back instead of at 1 kHz (the simulated hand and replays only).
    pub free_running: bool,
    /// Record the handle trace to this file.
    pub record: Option<PathBuf>,
    /// Write an assembly study into this folder after the session.
    pub study: Option<PathBuf>,
    /// The study's path table holds every Nth frame (and the last).
    pub study_every: usize,
    /// Print as JSON.
    pub json: bool,
    /// Also write the session report (JSON) to this file.
    pub report: Option<PathBuf>,
    /// Serve the live viewer on this address.
    pub view: Option<SocketAddr>,
    /// Bridge overrides.
    pub bridge: BridgeOverrides,
    /// With a replayed first part and several moving parts: each other part replays its own
    /// trace beside the first's ([`crate::session_files::part_trace_path`]) instead of its scene device.
    pub replay_every_part: bool,
}

impl Default for SessionRequest {
    fn default() -> Self {
        SessionRequest {
            scene: SceneRequest::default(),
            device: None,
            haptic: None,
            voxel_size: None,
            seconds: None,
            threads: 1,
            free_running: false,
            record: None,
            study: None,
            study_every: 1,
            json: false,
            report: None,
            view: None,
            bridge: BridgeOverrides::default(),
            replay_every_part: false,
        }
    }
}
