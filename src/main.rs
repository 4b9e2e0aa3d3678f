//! `vps`: the command-line front end of voxel-sampling haptic rendering.
//!
//! Every subcommand is a thin shell over the library crates: `vps-mesh` (input), `vps-voxelize`
//! (voxmaps and point shells), `vps-voxmap` (tree and files), `vps-haptic` (the frame),
//! `vps-device` and `vps-runtime` (the 1 kHz loop).

mod cli;
mod cmd;
mod demo;
mod scene;

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
        eprintln!("vps: error: {err:#}");
        std::process::exit(1);
    }
}
