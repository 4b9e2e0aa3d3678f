//! Command-line definitions (clap). Lengths accept SI metres or a unit suffix (`5mm`).

use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;
use vps_app::limits::{
    parse_bytes, parse_device, parse_force_scale, parse_frame_stride, parse_map_scale,
    parse_pose_timeout_ms, parse_triple,
};
use vps_app::{BridgeOverrides, SceneRequest, SessionRequest};
use vps_session::file::Units;
use vps_session::length::parse_length;

/// Voxel-sampling 6-DOF haptic rendering.
#[derive(Parser, Debug)]
#[command(name = "vps", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Voxelize a static scene (a mesh file or builtin:NAME) into a .vmap voxmap.
    Voxelize(VoxelizeArgs),
    /// Build the point shell of a dynamic object into a .vshell file.
    Shell(ShellArgs),
    /// Print statistics of a .vmap or .vshell file.
    Inspect(InspectArgs),
    /// Look up the voxel kind at world points listed in a CSV file (x,y,z per line, metres).
    Probe(ProbeArgs),
    /// The main job: a scene's scripted session with braking on (paced) and off (built-in
    /// scene bay-teapot: the teapot threading the aircraft bay with a simulated hand).
    Demo(DemoArgs),
    /// One paced 1 kHz session on a scene (default the built-in bay) with a chosen device.
    Run(RunArgs),
    /// Record the handle trace of a session to a file (JSON lines): `vps run --record FILE`.
    Record(RecordArgs),
    /// Replay a recorded handle trace exactly, on a scene (the one it was recorded on):
    /// `vps run --device replay:TRACE`.
    Replay(ReplayArgs),
    /// An assembly study from a recorded trace: the part's path recomputed on the scene, exact
    /// clearance to each static object, contact events and a verdict, as files in a folder.
    Study(StudyArgs),
    /// Scene files: check one without running it.
    Scene(SceneCommandArgs),
    /// List the HID devices this machine sees and which vps can drive.
    Devices {
        /// Print as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Make a self-signed certificate and key for a coordinator or worker (DIR/NAME.crt, .key).
    Cert {
        /// Output directory.
        #[arg(long, default_value = ".")]
        out: PathBuf,
        /// Name of the files and of the certificate's subject.
        #[arg(long)]
        name: String,
    },
    /// Cluster deployment: `vps deploy init` writes certificates, pins and configs for a list of
    /// hosts (or a loopback rehearsal), one folder per host.
    Deploy(DeployArgs),
    /// Run a worker: join a coordinator over QUIC and compute the shares it is given.
    Worker(WorkerArgs),
    /// Run the coordinator: the device loop, with workers from the LAN (pinned certificates).
    Coordinator(CoordinatorArgs),
    /// Coordinator plus N local worker processes on loopback (single-host multi-process mode).
    Cluster(ClusterArgs),
    /// UDP relay adding seeded delay, jitter and loss (netem in userspace) between workers and a coordinator.
    NetemRelay(NetemRelayArgs),
    /// Serve the live viewer page for an offline voxmap (inspect a scene before running it).
    View(ViewArgs),
    /// Measure; prints a text report (`--json`: the JSON that docs/results/ keeps).
    Bench(BenchArgs),
    /// Speed against accuracy over voxel sizes and shell methods, against the exact reference.
    Sweep(SweepArgs),
    /// Propose the finest voxel size whose frame p99.9 fits a budget on this machine, and verify it.
    Tune(TuneArgs),
}

/// Which scene a session runs, and whether its voxmap may come from the cache.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// The scene: a scene file (TOML; docs/scenes.md) or builtin:NAME (bay-teapot, rig-teapot).
    #[arg(long, default_value = vps_session::DEFAULT_SCENE)]
    pub scene: String,
    /// Always voxelize: neither read nor write the voxmap cache ($VPS_CACHE_DIR, else
    /// $XDG_CACHE_HOME/vps, else ~/.cache/vps).
    #[arg(long)]
    pub no_cache: bool,
    /// Memory budget of the whole scene (meshes, placed copies, voxelizer, voxmap, distance band,
    /// exact reference, winding-number trees, shell, viewer), estimated before anything is built
    /// and refused above it (bytes, or 16GiB, 512MiB, 8GB; default half of physical memory).
    #[arg(long, value_parser = parse_bytes, value_name = "SIZE")]
    pub max_memory: Option<u64>,
}

impl SceneArgs {
    /// The scene as the application layer takes it.
    pub fn request(&self) -> SceneRequest {
        SceneRequest {
            scene: self.scene.clone(),
            no_cache: self.no_cache,
            max_memory: self.max_memory,
        }
    }
}

/// Arguments of `vps scene`.
#[derive(Args, Debug)]
pub struct SceneCommandArgs {
    /// What to do with the scene.
    #[command(subcommand)]
    pub which: SceneCommand,
}

/// The `vps scene` subcommands.
#[derive(Subcommand, Debug)]
pub enum SceneCommand {
    /// Validate a scene without running it: triangles and bounds of every object and the part,
    /// estimated voxels and voxmap memory, shell points, and whether a frame fits the 1 ms period.
    Check {
        /// The scene file, or builtin:NAME.
        scene: String,
        /// Print as JSON.
        #[arg(long)]
        json: bool,
        /// Memory budget the whole scene's estimate is checked against, as a session's
        /// `--max-memory` (bytes, or 16GiB, 512MiB, 8GB; default half of physical memory).
        #[arg(long, value_parser = parse_bytes, value_name = "SIZE")]
        max_memory: Option<u64>,
    },
}

/// Arguments of `vps sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// The sweep file (voxel sizes, widths, methods, scene files). Default: the built-in one
    /// (configs/sweep.toml as built into vps; its scenes are the built-in scenes), so the sweep
    /// runs from any folder.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Print the table as JSON instead of text (`--json`), or write it to FILE (`--json FILE`;
    /// the text is printed then).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// Write the table as CSV here.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write one SVG plot per figure into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Test-sized run: each scene at its own voxel size and at twice it (one coarser), sessions
    /// cut to 2 s.
    #[arg(long)]
    pub quick: bool,
    /// Sweep this scene (file or builtin:NAME) instead of the sweep file's runs, over its sizes
    /// and methods.
    #[arg(long)]
    pub scene: Option<String>,
}

/// Arguments of `vps tune`.
#[derive(Args, Debug)]
pub struct TuneArgs {
    /// The scene to tune for: a scene file or builtin:NAME.
    #[arg(long, default_value = "builtin:rig-teapot")]
    pub scene: String,
    /// Always voxelize; never read or write the voxmap cache.
    #[arg(long)]
    pub no_cache: bool,
    /// Budget for frame compute p99.9, as a fraction of the 1 ms period.
    #[arg(long, default_value_t = 0.6)]
    pub budget_fraction: f64,
    /// Free-running frames measured per voxel size.
    #[arg(long, default_value_t = 5000)]
    pub frames: u64,
    /// Paced frames run at the chosen size to verify it.
    #[arg(long, default_value_t = 10_000)]
    pub verify_frames: u64,
    /// A sweep table (`vps sweep --json FILE`) for the predicted accuracy. Default: the built-in
    /// one (docs/sweep/sweep.json as built into vps: the built-in scenes' rows).
    #[arg(long, value_name = "FILE")]
    pub sweep: Option<PathBuf>,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vps view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    /// The voxmap to show (.vmap); or give --scene.
    #[arg(required_unless_present = "scene", conflicts_with = "scene")]
    pub voxmap: Option<PathBuf>,
    /// Show a scene (file or builtin:NAME): its voxmap (built or cached) and its part's shell.
    #[arg(long)]
    pub scene: Option<String>,
    /// With --scene: always voxelize; never read or write the voxmap cache.
    #[arg(long)]
    pub no_cache: bool,
    /// With --scene: memory budget of the whole scene (meshes, placed copies, voxelizer, voxmap,
    /// distance band, exact reference, winding-number trees, shell, viewer), estimated before
    /// anything is built and
    /// refused above it, as on the session commands (bytes, or 16GiB, 512MiB, 8GB; default half
    /// of physical memory).
    #[arg(long, value_parser = parse_bytes, value_name = "SIZE", requires = "scene")]
    pub max_memory: Option<u64>,
    /// A part's point shell (.vshell) to describe beside it.
    #[arg(long)]
    pub shell: Option<PathBuf>,
    /// With --scene: a study's folder (`--study DIR` of a session, or `vps study -o DIR`) to
    /// scrub along: the part's path, its closest approach and swept volume.
    #[arg(long, value_name = "DIR", requires = "scene")]
    pub study: Option<PathBuf>,
    /// Address to serve the page on.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub addr: std::net::SocketAddr,
}

/// Arguments of `vps netem-relay`.
#[derive(Args, Debug)]
pub struct NetemRelayArgs {
    /// Address workers send to (UDP).
    #[arg(long)]
    pub listen: std::net::SocketAddr,
    /// The coordinator's address.
    #[arg(long)]
    pub forward: std::net::SocketAddr,
    /// Mean one-way delay per datagram (e.g. 100us, 1ms).
    #[arg(long, value_parser = vps_netem::relay::parse_duration, default_value = "100us")]
    pub delay: std::time::Duration,
    /// Half-width of the uniform jitter around the delay.
    #[arg(long, value_parser = vps_netem::relay::parse_duration, default_value = "50us")]
    pub jitter: std::time::Duration,
    /// Probability of dropping a datagram, per direction (0..1).
    #[arg(long, default_value_t = 0.01)]
    pub loss: f64,
    /// Seed of the drop and delay draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Stop after this many seconds and print the figures (default: run until killed).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Print the final figures as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The TLS identity of a cluster service (`vps worker`, `vps coordinator`): its own certificate
/// and key, and the certificates of the peers it accepts.
#[derive(Args, Debug, Clone, Default, PartialEq)]
pub struct IdentityArgs {
    /// This worker's or coordinator's certificate (PEM). Required, here or in the config file.
    #[arg(long)]
    pub cert: Option<PathBuf>,
    /// This worker's or coordinator's private key (PEM). Required, here or in the config file.
    #[arg(long)]
    pub key: Option<PathBuf>,
    /// A peer certificate to accept (a worker pins its coordinator's, a coordinator its workers'),
    /// or a directory of them (*.crt); repeatable; any other is refused (and logged by a
    /// coordinator). At least one, here or in the config file (`pins`).
    #[arg(long)]
    pub pin: Vec<PathBuf>,
}

/// Arguments of `vps deploy`.
#[derive(Args, Debug)]
pub struct DeployArgs {
    /// What to do.
    #[command(subcommand)]
    pub which: DeployCommand,
}

/// The `vps deploy` subcommands.
#[derive(Subcommand, Debug)]
pub enum DeployCommand {
    /// Write a ready cluster layout into a new folder: per host its certificate and key, the
    /// peers' certificates to pin, and its coordinator.toml or worker.toml; README.txt says
    /// which command to run on which host. Never overwrites a file.
    Init(DeployInitArgs),
}

/// Arguments of `vps deploy init`.
#[derive(Args, Debug)]
pub struct DeployInitArgs {
    /// The coordinator host: `NAME=IP[:PORT]`, the address its workers dial (port default
    /// --port). It listens at that port on every interface (on a loopback address: on it).
    #[arg(
        long,
        value_name = "NAME=IP[:PORT]",
        required_unless_present = "loopback"
    )]
    pub coordinator: Option<String>,
    /// A worker host: NAME, or NAME=ADDR (the address is only written into README.txt:
    /// workers dial out and need no listening port). Repeat for each worker.
    #[arg(long, value_name = "NAME[=ADDR]", required_unless_present = "loopback")]
    pub worker: Vec<String>,
    /// A one-host rehearsal instead of --coordinator/--worker: a coordinator on 127.0.0.1 and N
    /// workers (1..=64) dialling it, every file ready to run from this machine.
    #[arg(long, value_name = "N", conflicts_with_all = ["coordinator", "worker"], value_parser = vps_app::limits::parse_workers)]
    pub loopback: Option<usize>,
    /// The coordinator's UDP port (1..=65535), where --coordinator gives none and with
    /// --loopback.
    #[arg(long, default_value_t = 7800, value_parser = clap::value_parser!(u16).range(1..))]
    pub port: u16,
    /// The folder to write (created; the files in it must not exist yet).
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub out: PathBuf,
    /// Print what was written as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vps worker`.
#[derive(Args, Debug)]
pub struct WorkerArgs {
    /// Read these settings from a TOML file (keys as the flags: configs/worker.toml); a flag
    /// given here overrides the file.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The coordinator's address (IP:port). Required, here or in the config file.
    #[arg(long, value_parser = vps_app::limits::parse_ip_port)]
    pub coordinator: Option<std::net::SocketAddr>,
    /// This worker's certificate, key and pinned coordinator certificates.
    #[command(flatten)]
    pub identity: IdentityArgs,
    /// Directory to cache scenes in, by content hash.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Compute threads (default: one per core).
    #[arg(long, value_parser = vps_app::limits::parse_count)]
    pub threads: Option<usize>,
    /// Exit (status 0) when the coordinator goes away instead of waiting for the next one.
    /// Without it the worker is a long-lived service: it re-joins (waits from 100 ms doubling
    /// to 5 s, with jitter) until SIGINT or SIGTERM; `vps cluster` passes it to its own
    /// workers so that none outlives it.
    #[arg(long)]
    pub exit_with_coordinator: bool,
}

/// Arguments of `vps coordinator`.
#[derive(Args, Debug)]
pub struct CoordinatorArgs {
    /// Read these settings from a TOML file (keys as the flags: configs/coordinator.toml); a
    /// flag given here overrides the file.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Address to listen on (UDP, QUIC).
    #[arg(long, default_value = "0.0.0.0:7800", value_parser = vps_app::limits::parse_ip_port)]
    pub listen: std::net::SocketAddr,
    /// The coordinator's certificate, key and pinned worker certificates.
    #[command(flatten)]
    pub identity: IdentityArgs,
    /// Workers to wait for before the session starts (1..=64: one class of the shell at least
    /// each).
    #[arg(long, default_value_t = 1, value_parser = vps_app::limits::parse_workers)]
    pub workers: usize,
    /// How long to wait for the workers to join before giving up (seconds, 0.1..=3600): long
    /// enough to start them by hand on their hosts.
    #[arg(long, value_name = "SECONDS", default_value_t = vps_app::DEFAULT_JOIN_WAIT.as_secs_f64(), value_parser = vps_app::limits::parse_join_wait)]
    pub join_wait: f64,
    /// How replies are gathered.
    #[command(flatten)]
    pub gather: GatherArgs,
    /// The session (device, parameters, length, recording).
    #[command(flatten)]
    pub session: RunArgs,
}

/// How the coordinator's frame thread gathers its workers' replies.
#[derive(Args, Debug, Clone, Copy)]
pub struct GatherArgs {
    /// Give every worker an equal share instead of adapting each share to its round trips.
    #[arg(long)]
    pub equal_shares: bool,
    /// Spin instead of sleeping on the reply queue for the last this many µs before the reply
    /// deadline. A value at least the reply window (half the watchdog budget: 400 µs in a
    /// session) busy-waits for every reply: one wake-up less per frame (one local worker's round
    /// trip p50 61–93 → 46–47 µs on the project's 2-core VM, docs/cluster.md), but the frame
    /// thread's core then does nothing else; use it only where each worker and the coordinator's
    /// network thread have cores of their own (two local workers on two cores: worst gather p99.9
    /// 0.2–0.5 → 4.1–4.2 ms).
    #[arg(long, default_value_t = default_spin_us())]
    pub spin_us: u64,
    /// A missing worker share whose local recompute cannot finish before the device write is due
    /// may be stood in for by its sums from up to this many frames earlier (degraded accuracy,
    /// counted as `stale_shares`); 0 always recomputes, so the wrench stays bit-identical to a
    /// one-process session whatever the timing.
    #[arg(long, default_value_t = default_max_stale_frames())]
    pub max_stale_frames: u64,
    /// How the classes are split: `predict` sends a worker its share only when its predicted
    /// round trip plus compute shortens the frame, measuring it with probes no frame waits for
    /// (a small shell then stays local); `always` splits every frame between all workers. The
    /// report's `cluster.split` says how often and why (`vps_cluster::GatherConfig::predict`).
    #[arg(long, value_enum, default_value_t = SplitMode::Predict)]
    pub split: SplitMode,
}

/// `--split`: when the coordinator sends work to its workers.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitMode {
    /// Only when that is predicted to shorten the frame.
    Predict,
    /// Every frame, to every worker not sidelined.
    Always,
}

impl GatherArgs {
    /// The gather settings these flags give ([`vps_cluster::GatherConfig`]'s defaults for the
    /// rest).
    pub fn config(&self) -> vps_cluster::GatherConfig {
        vps_cluster::GatherConfig {
            adaptive_shares: !self.equal_shares,
            predict: self.split == SplitMode::Predict,
            spin_margin: std::time::Duration::from_micros(self.spin_us),
            stale: vps_cluster::fallback::StalePolicy {
                max_age_frames: self.max_stale_frames,
                ..Default::default()
            },
            ..vps_cluster::GatherConfig::default()
        }
    }
}

/// The gatherer's default spin margin ([`vps_cluster::GatherConfig`]), in µs.
fn default_spin_us() -> u64 {
    vps_cluster::GatherConfig::default().spin_margin.as_micros() as u64
}

/// The gatherer's default age limit for stale stand-ins ([`vps_cluster::fallback::StalePolicy`]).
fn default_max_stale_frames() -> u64 {
    vps_cluster::fallback::StalePolicy::default().max_age_frames
}

/// Arguments of `vps cluster`.
#[derive(Args, Debug)]
pub struct ClusterArgs {
    /// Worker processes to start on this host.
    #[arg(long, value_parser = vps_app::limits::parse_count, default_value_t = 2)]
    pub local_workers: usize,
    /// Compute threads per worker process.
    #[arg(long, value_parser = vps_app::limits::parse_count, default_value_t = 1)]
    pub worker_threads: usize,
    /// How replies are gathered.
    #[command(flatten)]
    pub gather: GatherArgs,
    /// The session (device, parameters, length, recording).
    #[command(flatten)]
    pub session: RunArgs,
}

/// Arguments of `vps record`: those of `vps run`, the trace file given as `-o` instead of
/// `--record`.
#[derive(Args, Debug)]
pub struct RecordArgs {
    /// Output trace file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The session.
    #[command(flatten)]
    pub session: RunArgs,
}

/// Arguments of `vps replay`: those of `vps run`, the device being the trace.
#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// The trace file written by `vps record` or `vps run --record`.
    pub trace: PathBuf,
    /// The session.
    #[command(flatten)]
    pub session: RunArgs,
}

/// Arguments of `vps study`.
#[derive(Args, Debug)]
pub struct StudyArgs {
    /// The trace file written by `vps record` or `vps run --record`.
    pub trace: PathBuf,
    /// The folder the study's files are written into (made when missing).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// The scene the trace was recorded on.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Haptic parameters (TOML) the session ran with, instead of the scene's `[haptic]`.
    #[arg(long, value_name = "FILE")]
    pub haptic: Option<PathBuf>,
    /// Voxel size the session ran with, instead of the scene's.
    #[arg(long, value_parser = parse_length)]
    pub voxel_size: Option<f64>,
    /// The path table holds every Nth frame (and the last).
    #[arg(long, value_name = "N", value_parser = parse_frame_stride, default_value_t = 1)]
    pub every: usize,
    /// Voxel size of the swept volume. Default: the scene's voxel size.
    #[arg(long, value_parser = parse_length)]
    pub swept_voxel_size: Option<f64>,
    /// Print study.json's content instead of the text report.
    #[arg(long)]
    pub json: bool,
}

/// The voxel size, length and threads of a session (`vps run` and the commands built on it,
/// `vps demo`).
#[derive(Args, Debug, Clone)]
pub struct SessionSizeArgs {
    /// Voxel edge length (m, or with a unit: 2mm), instead of the scene's `voxels.voxel_size`.
    #[arg(long, value_parser = parse_length)]
    pub voxel_size: Option<f64>,
    /// Session length (s). Default: the simulated hand runs until its path has ended (its last
    /// hold included; about 70 s on the default scene); a replay, the length of its trace; any
    /// other device, 30 s.
    #[arg(long, value_parser = vps_app::limits::parse_seconds)]
    pub seconds: Option<f64>,
    /// Compute threads, the frame thread included.
    #[arg(long, value_parser = vps_app::limits::parse_count, default_value_t = 1)]
    pub threads: usize,
}

/// Arguments of `vps run`.
#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// The scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// The device: `sim` (simulated hand on the scene's script), `spacemouse` (first SpaceMouse
    /// found; input only), `bridge[:ADDR]` (UDP device bridge, default 127.0.0.1:7700),
    /// `replay:FILE` (a recorded trace). Default: the scene's `[device] kind`, else `sim`.
    #[arg(long, value_parser = parse_device)]
    pub device: Option<String>,
    /// Haptic parameters (TOML; see configs/haptic.toml), instead of the scene's `[haptic]`.
    /// Defaults are derived when absent.
    #[arg(long, value_name = "FILE")]
    pub haptic: Option<PathBuf>,
    /// Voxel size, length and threads.
    #[command(flatten)]
    pub sizes: SessionSizeArgs,
    /// Run the frames back to back instead of at 1 kHz on the wall clock (the simulated hand and
    /// replays only): the same physics, frame for frame, with no tick ever missed and no
    /// watchdog (nobody holds a device); for checks and tests that must not depend on the
    /// machine's load.
    #[arg(long)]
    pub free_running: bool,
    /// Record the handle trace to this file.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Write an assembly study of the session into this folder after it ends (docs/study.md):
    /// the part's path, exact clearance to each static object, contact events and a verdict.
    #[arg(long, value_name = "DIR")]
    pub study: Option<PathBuf>,
    /// The study's path table holds every Nth frame (and the last); its minimum clearance is
    /// over every frame whatever N is.
    #[arg(long, value_name = "N", value_parser = parse_frame_stride, default_value_t = 1)]
    pub study_every: usize,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also write the session report (JSON) to this file, however the session ends (a partial
    /// report says why). Checked before the session starts.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Serve the live viewer on this address (e.g. 127.0.0.1:8080; port 0 picks a free one).
    #[arg(long, value_name = "ADDR")]
    pub view: Option<std::net::SocketAddr>,
    /// Bridge device settings (only with `--device bridge[:ADDR]`).
    #[command(flatten)]
    pub bridge: BridgeArgs,
}

/// Settings of the UDP device bridge (`--device bridge[:ADDR]`); see docs/devices.md. Each flag
/// given replaces the scene file's `[device]` value (`mapping.*`, `pose_timeout_ms`); an absent
/// flag keeps the scene's, else the default.
#[derive(Args, Debug, Clone, Default, PartialEq)]
pub struct BridgeArgs {
    /// Scene metres per device metre (0.001 to 1000). Default: the scene's, else 1.
    #[arg(long, value_parser = parse_map_scale)]
    pub map_scale: Option<f64>,
    /// Scene position of the device origin, X,Y,Z (m). Default: the scene's, else 0,0,0.
    #[arg(long, value_parser = parse_triple, value_name = "X,Y,Z")]
    pub map_offset: Option<[f64; 3]>,
    /// Rotation from device axes to scene axes, degrees about X, Y, Z (X applied first).
    /// Default: the scene's, else 0,0,0.
    #[arg(long, value_parser = parse_triple, value_name = "RX,RY,RZ")]
    pub map_rotate_deg: Option<[f64; 3]>,
    /// Device force per scene force (also scales torque), before the device's limits.
    /// Default: the scene's, else 1.
    #[arg(long, value_parser = parse_force_scale)]
    pub force_scale: Option<f64>,
    /// A device silent this long is held with zero output, and re-anchored when it resumes (ms,
    /// 2 to 10000). Default: the scene's, else 50.
    #[arg(long, value_parser = parse_pose_timeout_ms)]
    pub pose_timeout_ms: Option<f64>,
    /// Write every wrench sent to the device to this file (one line per wrench: frame, then the
    /// six f64 bit patterns in hex; format in docs/devices.md).
    #[arg(long, value_name = "FILE")]
    pub log_wrenches: Option<PathBuf>,
}

/// Where a mesh comes from: a file path or `builtin:NAME`.
pub type MeshSource = String;

/// Arguments of `vps voxelize`.
#[derive(Args, Debug)]
pub struct VoxelizeArgs {
    /// Mesh file (.obj, .stl, .ply; .step/.stp tessellated to a quarter voxel) or builtin:NAME (teapot, aircraft-bay, box, sphere, cylinder).
    pub mesh: MeshSource,
    /// Voxel edge length (m, or with unit: 5mm).
    #[arg(long, value_parser = parse_length, default_value = "5mm")]
    pub voxel_size: f64,
    /// Force-layer offset in voxel layers.
    #[arg(long, default_value_t = 2)]
    pub offset: u32,
    /// Tree branching: log2 children per axis at every level (3 = the paper's 512-tree).
    #[arg(long, default_value_t = 3)]
    pub tree_n: u8,
    /// Bits per voxel: 2 (kinds only, the paper's), 4 or 8 (kinds plus distance layers). The
    /// default, 4, is what scene files default to (the sweep's recommendation, docs/sweep.md).
    #[arg(long, default_value_t = 4)]
    pub width: u32,
    /// Voxelize only the region the part can reach: MINX,MINY,MINZ,MAXX,MAXY,MAXZ (m).
    #[arg(long)]
    pub workspace: Option<String>,
    /// The memory budget, the output file and the report's format.
    #[command(flatten)]
    pub build: BuildArgs,
}

/// What a command building a file from a mesh (`vps voxelize`, `vps shell`) may spend, where it
/// writes, and how it reports.
#[derive(Args, Debug)]
pub struct BuildArgs {
    /// Working-memory budget: the voxelizer estimates its peak from the plan before working and
    /// refuses above it (bytes, or 16GiB, 512MiB, 8GB; default half of physical memory).
    #[arg(long, value_parser = parse_bytes, value_name = "SIZE")]
    pub max_memory: Option<u64>,
    /// Units of the mesh file's coordinates (m, cm, mm, in), converted to metres before anything
    /// else (as a scene file's `units`); built-in meshes are in metres.
    #[arg(long, default_value = "m")]
    pub units: Units,
    /// Output file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the statistics as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Point-shell placement on the command line.
#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum ShellMethodArg {
    /// Centres of the object's Surface voxels (the paper).
    Centres,
    /// One point per Surface voxel on the exact mesh surface.
    Exact,
}

/// Arguments of `vps shell`.
#[derive(Args, Debug)]
pub struct ShellArgs {
    /// Mesh file or builtin:NAME.
    pub mesh: MeshSource,
    /// Voxel edge length (m, or with unit).
    #[arg(long, value_parser = parse_length, default_value = "5mm")]
    pub voxel_size: f64,
    /// Point placement: `exact` (one point per surface voxel on the mesh surface; the default,
    /// as in scene files) or `centres` (the paper's: at the voxel centre).
    #[arg(long, value_enum, default_value_t = ShellMethodArg::Exact)]
    pub method: ShellMethodArg,
    /// The memory budget, the output file and the report's format.
    #[command(flatten)]
    pub build: BuildArgs,
}

/// Arguments of `vps inspect`.
#[derive(Args, Debug)]
pub struct InspectArgs {
    /// A .vmap or .vshell file.
    pub file: PathBuf,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vps probe`.
#[derive(Args, Debug)]
pub struct ProbeArgs {
    /// The voxmap.
    pub voxmap: PathBuf,
    /// CSV file of world points, one `x,y,z` per line (m); blank lines, lines starting with # and
    /// a first line of words (a header such as `x,y,z`) skipped.
    #[arg(long)]
    pub points: PathBuf,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vps demo`.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// The scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Voxel size, length (of each of the two sessions) and threads. One thread is right for
    /// the teapot's few hundred points at 5 mm: handing a share to another thread costs more
    /// than computing it.
    #[command(flatten)]
    pub sizes: SessionSizeArgs,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write an assembly study of the braking-on session into this folder (docs/study.md).
    #[arg(long, value_name = "DIR")]
    pub study: Option<PathBuf>,
    /// The study's path table holds every Nth frame (and the last).
    #[arg(long, value_name = "N", value_parser = parse_frame_stride, default_value_t = 1)]
    pub study_every: usize,
    /// Serve the live viewer on this address (e.g. 127.0.0.1:8080; port 0 picks a free one).
    #[arg(long, value_name = "ADDR")]
    pub view: Option<std::net::SocketAddr>,
}

/// Arguments of `vps bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Which measurement.
    #[command(subcommand)]
    pub which: BenchKind,
    /// Print the report as JSON (the form docs/results/ keeps) instead of text.
    #[arg(long, global = true)]
    pub json: bool,
}

/// The benchmarks.
#[derive(Subcommand, Debug)]
pub enum BenchKind {
    /// Time and peak memory to voxelize a scene; voxmap memory; tree/dense lookup cost ratio.
    Voxelize {
        /// Scene (builtin:NAME or file).
        #[arg(default_value = "builtin:aircraft-bay")]
        mesh: MeshSource,
        /// Voxel edge length.
        #[arg(long, value_parser = parse_length, default_value = "5mm")]
        voxel_size: f64,
        /// Repetitions (the median is reported).
        #[arg(long, default_value_t = 3)]
        repeat: u32,
    },
    /// Nanoseconds per point of the sampling kernel, free space and full contact, one core: the
    /// current and the previous kernel alternated, and their ratio.
    Kernel {
        /// Shell sizes to measure.
        #[arg(long, value_delimiter = ',', default_value = "10000,100000,1000000")]
        points: Vec<usize>,
        /// Seconds per timing batch (5 batches per case, the median is reported).
        #[arg(long, value_parser = vps_app::limits::parse_seconds, default_value_t = 0.2)]
        seconds: f64,
    },
    /// The 1 kHz loop end to end over many frames with a large shell: missed deadlines, percentiles.
    Loop {
        /// The scene.
        #[command(flatten)]
        scene: SceneArgs,
        /// Voxel size, instead of the scene's.
        #[arg(long, value_parser = parse_length)]
        voxel_size: Option<f64>,
        /// Approximate number of shell points.
        #[arg(long, default_value_t = 100_000)]
        points: usize,
        /// Frames to run (1 ms each).
        #[arg(long, default_value_t = 100_000)]
        frames: u64,
        /// Compute threads, the frame thread included.
        #[arg(long, value_parser = vps_app::limits::parse_count, default_value_t = 2)]
        threads: usize,
    },
    /// Frame compute of a scene of several parts (default assets/scenes/two-hands.toml): the
    /// first part alone, the second alone, both apart (the broad phase skipping the pair), both
    /// apart with every pair sampled, and the scene's own touching session.
    Parts {
        /// The scene (of at least two `[[part]]`s).
        #[command(flatten)]
        scene: SceneArgs,
        /// Frames per run, back to back.
        #[arg(long, default_value_t = 3000)]
        frames: u64,
        /// Rounds: each configuration once per round, alternating.
        #[arg(long, default_value_t = 3)]
        rounds: u32,
    },
    /// Frame compute of the paced demo session without and with a connected viewer.
    Viewer {
        /// Session length per run (s).
        #[arg(long, value_parser = vps_app::limits::parse_seconds, default_value_t = 10.0)]
        seconds: f64,
        /// Rounds of one run without and one with the viewer.
        #[arg(long, default_value_t = 3)]
        rounds: u32,
    },
    /// A paced session over W local worker processes with an N-point shell: deadlines, frame times, per-worker metrics.
    Cluster {
        /// Approximate number of shell points.
        #[arg(long, default_value_t = 100_000)]
        points: usize,
        /// Frames to run (1 ms each).
        #[arg(long, default_value_t = 100_000)]
        frames: u64,
        /// Worker processes.
        #[arg(long, value_parser = vps_app::limits::parse_count, default_value_t = 2)]
        workers: usize,
        /// Compute threads per worker process.
        #[arg(long, value_parser = vps_app::limits::parse_count, default_value_t = 1)]
        worker_threads: usize,
        /// Compute threads of the coordinator.
        #[arg(long, value_parser = vps_app::limits::parse_count, default_value_t = 1)]
        threads: usize,
        /// The scene.
        #[command(flatten)]
        scene: SceneArgs,
        /// Voxel size, instead of the scene's.
        #[arg(long, value_parser = parse_length)]
        voxel_size: Option<f64>,
        /// How replies are gathered.
        #[command(flatten)]
        gather: GatherArgs,
    },
    /// How often this machine takes the frame thread's core away (cyclictest-like): ticks a loop
    /// doing `--busy-us` of work per 1 ms frame would miss with no haptics in it.
    Host {
        /// Length of the measurement (s).
        #[arg(long, value_parser = vps_app::limits::parse_seconds, default_value_t = 100.0)]
        seconds: f64,
        /// Work per frame, spun (µs).
        #[arg(long, default_value_t = 500)]
        busy_us: u64,
    },
    /// Analytic fidelity benchmark: voxel force and torque against the exact answer on five
    /// scenes (sphere, tilted box, corner, peg in hole, wedge) over separations −s..3s, per voxel
    /// size, bits per voxel and shell method, plus the sliding force's frame-to-frame jump.
    Fidelity {
        /// Voxel sizes.
        #[arg(long, value_delimiter = ',', value_parser = parse_length, default_value = "10mm,5mm,2.5mm,1.25mm")]
        voxel_sizes: Vec<f64>,
        /// Poses per scene and separation.
        #[arg(long, default_value_t = 8)]
        poses: usize,
        /// Force models: `tangent-plane` (the paper's), `distance` (signed-distance band,
        /// default stand-off of half a voxel), or both.
        #[arg(long, value_delimiter = ',', default_value = "tangent-plane,distance")]
        models: Vec<FidelityModelArg>,
    },
    /// Pegs (square, round) pushed by the hand into holes with 0.1 to 2 voxels of clearance a
    /// side, at 2 and 1 mm voxels, with the tangent-plane model and the distance model at half, an eighth and a sixteenth of a voxel of
    /// stand-off: whether each entered, the minimum
    /// exact separation and the penetrating frames (docs/fidelity.md, Clearance).
    Clearance,
    /// Device bridge round trip (pose out, wrench back), immediate and at 1 kHz, beside a raw
    /// UDP ping-pong.
    Bridge {
        /// Round trips per measurement (100 to 1000000).
        #[arg(long, default_value_t = 5000)]
        round_trips: u64,
    },
    /// Gather round trip to 1 and 2 local worker processes beside a raw UDP ping-pong.
    Transport {
        /// Frames (and raw UDP round trips) per measurement.
        #[arg(long, default_value_t = 5000)]
        frames: u64,
        /// Spin instead of sleeping for the last this many µs before the reply deadline (see
        /// `vps coordinator --help`).
        #[arg(long, default_value_t = default_spin_us())]
        spin_us: u64,
    },
    /// Total tree memory against N = 1..5 (the paper's Figure 6).
    TreeMemory {
        /// Scene.
        #[arg(default_value = "builtin:aircraft-bay")]
        mesh: MeshSource,
        /// Voxel edge length.
        #[arg(long, value_parser = parse_length, default_value = "5mm")]
        voxel_size: f64,
        /// Write an SVG plot here.
        #[arg(long)]
        plot: Option<PathBuf>,
    },
    /// Points per frame that fit the compute budget at p99.9, over 1..N local threads and 1..N
    /// local worker processes, and the parallel efficiency (child `vps bench loop` and
    /// `vps bench cluster` runs).
    Scaling {
        /// Largest thread and worker-process count (default: the machine's cores).
        #[arg(long)]
        max: Option<usize>,
        /// Shell sizes each configuration runs at (at least two).
        #[arg(long, value_delimiter = ',', default_value = "20000,100000")]
        points: Vec<usize>,
        /// Frames per run (1 ms each).
        #[arg(long, default_value_t = 3000)]
        frames: u64,
        /// Compute budget per frame (µs) that p99.9 must meet.
        #[arg(long, default_value_t = 1000.0)]
        budget_us: f64,
        /// Write an SVG plot here.
        #[arg(long)]
        plot: Option<PathBuf>,
    },
}

impl DemoArgs {
    /// The demo's session as the application layer takes it ([`vps_app::demo::run`]).
    pub fn request(&self) -> SessionRequest {
        SessionRequest {
            scene: self.scene.request(),
            voxel_size: self.sizes.voxel_size,
            seconds: self.sizes.seconds,
            threads: self.sizes.threads,
            json: self.json,
            study: self.study.clone(),
            study_every: self.study_every,
            view: self.view,
            ..SessionRequest::default()
        }
    }
}

impl DeployInitArgs {
    /// The layout as `vps_deploy::layout` takes it.
    pub fn request(&self) -> vps_deploy::layout::DeployRequest {
        vps_deploy::layout::DeployRequest {
            coordinator: self.coordinator.clone(),
            worker: self.worker.clone(),
            loopback: self.loopback,
            port: self.port,
            out: self.out.clone(),
            json: self.json,
        }
    }
}

impl SweepArgs {
    /// The sweep as `vps_bench::sweep` takes it.
    pub fn request(&self) -> vps_bench::sweep::SweepRequest {
        vps_bench::sweep::SweepRequest {
            config: self.config.clone(),
            json: self.json.clone(),
            csv: self.csv.clone(),
            plots: self.plots.clone(),
            quick: self.quick,
            scene: self.scene.clone(),
        }
    }
}

impl TuneArgs {
    /// The tuning as `vps_bench::tune` takes it.
    pub fn request(&self) -> vps_bench::tune::TuneRequest {
        vps_bench::tune::TuneRequest {
            scene: self.scene.clone(),
            no_cache: self.no_cache,
            budget_fraction: self.budget_fraction,
            frames: self.frames,
            verify_frames: self.verify_frames,
            sweep: self.sweep.clone(),
            json: self.json,
        }
    }
}

impl RunArgs {
    /// The session as the application layer takes it ([`vps_app::prepare()`]).
    pub fn request(&self) -> SessionRequest {
        let b = &self.bridge;
        SessionRequest {
            scene: self.scene.request(),
            device: self.device.clone(),
            haptic: self.haptic.clone(),
            voxel_size: self.sizes.voxel_size,
            seconds: self.sizes.seconds,
            threads: self.sizes.threads,
            free_running: self.free_running,
            record: self.record.clone(),
            study: self.study.clone(),
            study_every: self.study_every,
            json: self.json,
            report: self.report.clone(),
            view: self.view,
            bridge: BridgeOverrides {
                map_scale: b.map_scale,
                map_offset: b.map_offset,
                map_rotate_deg: b.map_rotate_deg,
                force_scale: b.force_scale,
                pose_timeout_ms: b.pose_timeout_ms,
                log_wrenches: b.log_wrenches.clone(),
            },
            replay_every_part: false,
        }
    }
}

/// A force model of `vps bench fidelity --models`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FidelityModelArg {
    /// The paper's tangent-plane model on the voxel layers.
    TangentPlane,
    /// The signed-distance band at its default stand-off (half a voxel).
    Distance,
}

impl FidelityModelArg {
    /// The force model it names.
    pub fn model(self) -> vps_fidelity::measure::ForceModel {
        match self {
            FidelityModelArg::TangentPlane => vps_fidelity::measure::ForceModel::TangentPlane,
            FidelityModelArg::Distance => vps_fidelity::measure::ForceModel::DISTANCE,
        }
    }
}
