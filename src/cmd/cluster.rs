//! `vps cert`, `vps worker`, `vps coordinator` and `vps cluster`: the cluster modes over QUIC
//! (docs/architecture.md#exact-sums-and-the-cluster), thin shells over `vps-cluster`.

use crate::cli::{ClusterArgs, CoordinatorArgs, WorkerArgs};
use crate::service_config::{resolve_coordinator, resolve_worker};
use anyhow::{bail, Result};
use clap::ArgMatches;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use vps_app::exit::SessionExit;
use vps_app::{prepare, Backend, ClusterBackend, Workers};
use vps_cluster::{make_cert, run_worker_service, ClusterError, PeerTls, Rejoin, WorkerConfig};
use vps_deploy::service_files::expand_pins;
use vps_runtime::SignalStop;

/// `vps cert`: a new self-signed certificate and key for a coordinator or worker.
pub fn cert(out: &std::path::Path, name: &str) -> Result<()> {
    let files = make_cert(out, name)?;
    println!("certificate {}", files.cert.display());
    println!(
        "key         {} (keep private; pin the certificate on the other side)",
        files.key.display()
    );
    let cert = vps_cluster::tls::load_cert(&files.cert)?;
    println!("sha256      {}", vps_cluster::tls::fingerprint(&cert));
    println!(
        "            (the SHA-256 of the certificate's DER, as a refusing peer logs it and `{}` prints it; compare it on both ends)",
        vps_cluster::tls::FINGERPRINT_COMMAND.replace("FILE", &files.cert.display().to_string())
    );
    Ok(())
}

/// Exit status of a worker refused for good (a certificate not pinned on one side, an
/// incompatible protocol): systemd units keep it from restarting (`RestartPreventExitStatus=`).
const EXIT_REFUSED: i32 = 2;

/// `vps worker`: joins a coordinator and answers frame requests; when the coordinator goes away,
/// waits for the next one (unless `--exit-with-coordinator`), until SIGINT or SIGTERM (exit 0).
/// A refusal for good exits with status 2 and says why. `matches` (the subcommand's) tell which
/// flags override the `--config` file's settings.
pub fn worker(mut args: WorkerArgs, matches: &ArgMatches) -> Result<()> {
    resolve_worker(&mut args, matches)?;
    let (Some(coordinator), Some(cert), Some(key)) =
        (args.coordinator, &args.identity.cert, &args.identity.key)
    else {
        bail!("vps worker: --coordinator, --cert and --key are required");
    };
    let pins = expand_pins(&args.identity.pin)?;
    let mut config = WorkerConfig::new(coordinator, PeerTls::load(cert, key, &pins)?);
    config.cache_dir = args.cache.clone();
    if let Some(threads) = args.threads {
        config.threads = threads.max(1);
    }
    let stop = Arc::new(AtomicBool::new(false));
    let signals = SignalStop::install(&stop)?;
    let rejoin = Rejoin {
        exit_with_coordinator: args.exit_with_coordinator,
        ..Rejoin::default()
    };
    match run_worker_service(config, stop, rejoin) {
        Ok(service) => {
            let why = signals
                .received()
                .map_or("its coordinator went away", |s| s.name());
            eprintln!(
                "worker stopped ({why}) after {} session(s)",
                service.sessions.len()
            );
            Ok(())
        }
        Err(ClusterError::Refused(reason)) => Err(SessionExit {
            code: EXIT_REFUSED,
            reason: format!("worker refused for good: {reason}"),
        }
        .into()),
        Err(e) => Err(anyhow::Error::new(e).context("worker")),
    }
}

/// `vps coordinator`: owns the device loop; workers from the LAN join with pinned certificates.
/// `matches` (the subcommand's) tell which flags override the `--config` file's settings.
pub fn coordinator(mut args: CoordinatorArgs, matches: &ArgMatches) -> Result<()> {
    resolve_coordinator(&mut args, matches)?;
    let (Some(cert), Some(key)) = (&args.identity.cert, &args.identity.key) else {
        bail!("vps coordinator: --cert and --key are required");
    };
    let pins = expand_pins(&args.identity.pin)?;
    // Mistakes in the certificates or the address are reported before the voxmap is built.
    let tls = PeerTls::load(cert, key, &pins)?;
    check_listen_address(args.listen)?;
    prepare(&args.session.request())?.run(Backend::Cluster(Box::new(ClusterBackend {
        workers: Workers::Lan {
            listen: args.listen,
            tls,
            count: args.workers,
            join_wait: std::time::Duration::from_secs_f64(args.join_wait),
        },
        gather: args.gather.config(),
    })))
}

/// Whether a UDP socket can be bound on `listen` now (the port free, the address this host's):
/// the coordinator's QUIC endpoint binds it for real once the scene is ready.
fn check_listen_address(listen: std::net::SocketAddr) -> Result<()> {
    match std::net::UdpSocket::bind(listen) {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AddrInUse => bail!(
            "cannot listen on UDP {listen}: {e}; another process holds that port (another vps coordinator? `ss -ulpn 'sport = :{}'` shows which), or choose another `listen` port",
            listen.port()
        ),
        Err(e) => bail!("cannot listen on UDP {listen}: {e}"),
    }
}

/// `vps cluster --local-workers N`: the coordinator plus N worker processes on loopback, with
/// fresh certificates pinned both ways.
pub fn local_cluster(args: &ClusterArgs) -> Result<()> {
    vps_app::limits::check_thread_total(
        "--local-workers × --worker-threads",
        args.local_workers * args.worker_threads,
    )?;
    prepare(&args.session.request())?.run(Backend::Cluster(Box::new(ClusterBackend {
        workers: Workers::Local {
            count: args.local_workers,
            threads: args.worker_threads,
        },
        gather: args.gather.config(),
    })))
}
