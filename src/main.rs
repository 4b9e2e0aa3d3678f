//! `vps`: the command-line front end of voxel-sampling haptic rendering: the command line,
//! dispatch and printing, and nothing else (`tests/binary_layout.rs` holds it to 3,000 lines and
//! checks that no command module builds a session).
//!
//! Every subcommand is a shell over the library crates (docs/architecture.md draws them): the
//! application layer `vps-app` (a session prepared from a request and run locally or with
//! workers, its end, report and study; `vps demo`; `vps scene check`), `vps-bench` (the
//! benchmarks, sweep and tune), `vps-deploy` (the services' config files and `vps deploy init`),
//! and below them `vps-session` (scene files and their assets), `vps-runtime` (the 1 kHz loop),
//! `vps-haptic` (the frame), `vps-cluster` (coordinator and workers), `vps-view` (the browser
//! viewer), `vps-study` (a session's evidence), `vps-fidelity` (the analytic benchmark),
//! `vps-mesh`, `vps-step`, `vps-voxelize`, `vps-voxmap`, `vps-device` and `vps-input`.
//!
//! Layout: [`cli`] (the command line; each session command's flags become a
//! `vps_app::SessionRequest`), `cmd/` (one module per subcommand; none imports another), and the
//! modules they share, which import no subcommand: [`service_config`] (a cluster service's
//! `--config` file merged under its flags), [`mesh_arg`] (the mesh argument of `voxelize` and
//! `shell`).

mod cli;
mod cmd;
mod mesh_arg;
mod service_config;

use clap::{CommandFactory, FromArgMatches};

/// The log filter without `RUST_LOG`: warnings, and the cluster services' joins and departures
/// (a worker's "joined", a coordinator's "worker N at ADDR joined / left"), which an admin reading
/// the journal needs to see; the per-second worker figures stay at `RUST_LOG=vps_cluster=info`.
const DEFAULT_LOG_FILTER: &str = "warn,vps_cluster::worker=info,vps_cluster::coordinator=info";

fn main() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(DEFAULT_LOG_FILTER)),
        )
        .with_writer(std::io::stderr)
        // Colour codes only on a terminal: not in a file, a pipe or the systemd journal.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let matches = cli::Cli::command().get_matches();
    let cli = cli::Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Err(err) = cmd::dispatch(cli, &matches) {
        // stdout's reader went away (`vps inspect x | head -1`): end quietly, as SIGPIPE would.
        if err.is::<vps_app::output::BrokenStdout>() {
            std::process::exit(vps_app::output::BROKEN_PIPE_STATUS);
        }
        // A session that ended early has already written its report; its status says why
        // (src/exit.rs: 1 error, 101 panic, 128 + N signal N).
        let code = vps_app::exit::exit_code(&err);
        let message = vps_app::output::shown_error(&vps_session::error::error_chain_text(&err));
        if code == 1 {
            eprintln!("vps: error: {message}");
        } else {
            eprintln!("vps: {message}");
        }
        std::process::exit(code);
    }
}
