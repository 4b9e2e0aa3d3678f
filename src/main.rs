//! `vps`: the command-line front end of voxel-sampling haptic rendering.
//!
//! Every subcommand is a thin shell over the library crates: `vps-mesh` (input), `vps-voxelize`
//! (voxmaps and point shells), `vps-voxmap` (tree and files), `vps-haptic` (the frame),
//! `vps-device` and `vps-runtime` (the 1 kHz loop).

mod cli;
mod cmd;
mod demo;
mod kernel_timing;
mod limits;
mod memory_size;
mod scene;
mod svg;
mod sweep_session;

use clap::Parser;

fn main() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = cli::Cli::parse();
    if let Err(err) = cmd::dispatch(cli) {
        // stdout's reader went away (`vps inspect x | head -1`): end quietly, as SIGPIPE would.
        if err.is::<cmd::output::BrokenStdout>() {
            std::process::exit(cmd::output::BROKEN_PIPE_STATUS);
        }
        // A session that ended early has already written its report; its status says why
        // (src/cmd/exit.rs: 1 error, 101 panic, 128 + N signal N).
        let code = cmd::exit::exit_code(&err);
        let message = cmd::output::error_report(&err);
        if code == 1 {
            eprintln!("vps: error: {message}");
        } else {
            eprintln!("vps: {message}");
        }
        std::process::exit(code);
    }
}
