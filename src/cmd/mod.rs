//! One module per subcommand; [`dispatch`] routes the parsed command line.

mod cluster;

mod inspect;
mod netem_relay;
mod probe;
mod run;

mod shell;
mod study;
mod view;
mod voxelize;

use crate::cli::{BenchKind, Cli, Command, DeployCommand, FidelityModelArg, SceneCommand};
use anyhow::Result;
use clap::ArgMatches;

/// Runs the parsed command; `matches` are what it was parsed from (the service commands merge
/// their `--config` file under the flags given on the command line).
pub fn dispatch(cli: Cli, matches: &ArgMatches) -> Result<()> {
    let sub = |name: &str| {
        matches
            .subcommand_matches(name)
            .cloned()
            .unwrap_or_default()
    };
    match cli.command {
        Command::Voxelize(args) => voxelize::run(&args),
        Command::Shell(args) => shell::run(&args),
        Command::Inspect(args) => inspect::run(&args),
        Command::Probe(args) => probe::run(&args),
        Command::Demo(args) => vps_app::demo::run(&args.request()),
        Command::Run(args) => run::run(&args),
        Command::Record(args) => run::record(&args),
        Command::Replay(args) => run::replay(&args),
        Command::Study(args) => study::run(&args),
        Command::Scene(args) => match args.which {
            SceneCommand::Check {
                scene,
                json,
                max_memory,
            } => vps_app::scene_check::run(&scene, json, max_memory),
        },
        Command::Devices { json } => run::devices(json),
        Command::Cert { out, name } => cluster::cert(&out, &name),
        Command::Deploy(args) => match args.which {
            DeployCommand::Init(args) => vps_deploy::layout::init(&args.request()),
        },
        Command::Worker(args) => cluster::worker(args, &sub("worker")),
        Command::Coordinator(args) => cluster::coordinator(args, &sub("coordinator")),
        Command::Cluster(args) => cluster::local_cluster(&args),
        Command::NetemRelay(args) => netem_relay::run(&args),
        Command::View(args) => view::run(&args),
        Command::Sweep(args) => vps_bench::sweep::run(&args.request()),
        Command::Tune(args) => vps_bench::tune::run(&args.request()),
        Command::Bench(args) => {
            let json = args.json;
            match args.which {
            BenchKind::Voxelize {
                mesh,
                voxel_size,
                repeat,
                ..
            } => vps_bench::voxelize::run_voxelize(&mesh, voxel_size, repeat, json),
            BenchKind::TreeMemory {
                mesh,
                voxel_size,
                plot,
                ..
            } => vps_bench::voxelize::run_tree_memory(&mesh, voxel_size, plot.as_deref(), json),
            BenchKind::Loop {
                scene,
                voxel_size,
                points,
                frames,
                threads,
                ..
            } => vps_bench::frame_loop::run(&scene.request(), voxel_size, points, frames, threads, json),
            BenchKind::Parts {
                scene,
                frames,
                rounds,
                ..
            } => vps_bench::parts::run(&scene.request(), frames, rounds, json),
            BenchKind::Viewer {
                seconds, rounds, ..
            } => vps_bench::viewer::run(seconds, rounds, json),
            BenchKind::Transport {
                frames, spin_us, ..
            } => vps_bench::transport::run(frames, spin_us, json),
            BenchKind::Bridge { round_trips, .. } => vps_bench::bridge::run(round_trips, json),
            BenchKind::Host {
                seconds, busy_us, ..
            } => vps_bench::host::run(seconds, busy_us, json),
            BenchKind::Cluster {
                points,
                frames,
                workers,
                worker_threads,
                threads,
                scene,
                voxel_size,
                gather,
                ..
            } => vps_bench::cluster::run(vps_bench::cluster::ClusterBench {
                scene: scene.request(),
                voxel_size,
                points,
                frames,
                workers,
                worker_threads,
                local_threads: threads,
                gather: gather.config(),
            }, json),
            BenchKind::Kernel {
                points, seconds, ..
            } => vps_app::output::print_report(
                "bench kernel: ns per point of the sampling kernel, free space and full contact",
                &vps_bench::kernel::run(&points, seconds)?,
                json,
            ),
            BenchKind::Clearance => vps_app::output::print_report(
                "bench clearance: pegs pushed into holes of 0.1 to 2 voxels of clearance a side",
                &vps_fidelity::clearance::run(&vps_fidelity::clearance::ClearanceGrid::full())?,
                json,
            ),
            BenchKind::Fidelity {
                voxel_sizes,
                poses,
                models,
                ..
            } => vps_bench::fidelity::run(
                voxel_sizes,
                poses,
                models.into_iter().map(FidelityModelArg::model).collect(),
                json,
            ),
            BenchKind::Scaling {
                max,
                points,
                frames,
                budget_us,
                plot,
                ..
            } => vps_bench::scaling::run(
                &vps_bench::scaling::ScalingBench {
                    max_units: max.unwrap_or_else(|| {
                        std::thread::available_parallelism().map_or(1, |n| n.get())
                    }),
                    points,
                    frames,
                    budget_us,
                },
                plot.as_deref(),
                json,
            ),
            }
        }
    }
}
