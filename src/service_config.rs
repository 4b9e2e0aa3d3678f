//! `vps coordinator --config FILE` and `vps worker --config FILE`: a service's config file
//! ([`vps_deploy::service_files`]: its keys, one per flag, and its relative paths) merged under
//! the flags given on the command line (a flag given overrides the file's value).

use crate::cli::{CoordinatorArgs, IdentityArgs, WorkerArgs};
use anyhow::{anyhow, bail, Result};
use clap::parser::ValueSource;
use clap::ArgMatches;
use std::path::{Path, PathBuf};
use vps_deploy::service_files::{
    all_beside, beside, device_beside, load_coordinator, load_worker, scene_beside,
};
use vps_session::length::{parse_length, parse_length_string};

/// Whether the argument `id` (the field's name) was given on the command line.
fn given(matches: &ArgMatches, id: &str) -> bool {
    matches.value_source(id) == Some(ValueSource::CommandLine)
}

/// Sets `target` to the file's `value` unless the flag `id` was given on the command line.
fn take<T>(matches: &ArgMatches, id: &str, target: &mut T, value: Option<T>) {
    if let Some(v) = value {
        if !given(matches, id) {
            *target = v;
        }
    }
}

/// Checks a file value with the flag's own parser (same range and message), naming file and key.
fn checked<T>(
    path: &Path,
    key: &str,
    value: Option<impl ToString>,
    parse: fn(&str) -> Result<T, String>,
) -> Result<Option<T>> {
    value
        .map(|v| parse(&v.to_string()).map_err(|e| anyhow!("{}: `{key}`: {e}", path.display())))
        .transpose()
}

/// `vps worker`: merges `--config FILE` (when given) under the command-line flags of `matches`
/// (the worker subcommand's), then checks that the required settings are there.
pub fn resolve_worker(args: &mut WorkerArgs, matches: &ArgMatches) -> Result<()> {
    if let Some(path) = args.config.clone() {
        let f = load_worker(&path)?;
        let threads = checked(&path, "threads", f.threads, vps_app::limits::parse_count)?;
        let ip_port = vps_app::limits::parse_ip_port;
        let coordinator = checked(&path, "coordinator", f.coordinator, ip_port)?;
        take(
            matches,
            "coordinator",
            &mut args.coordinator,
            coordinator.map(Some),
        );
        take_identity(matches, &mut args.identity, &path, f.cert, f.key, f.pins);
        let cache = f.cache.map(|p| Some(beside(&path, p)));
        take(matches, "cache", &mut args.cache, cache);
        take(matches, "threads", &mut args.threads, threads.map(Some));
        take(
            matches,
            "exit_with_coordinator",
            &mut args.exit_with_coordinator,
            f.exit_with_coordinator,
        );
    }
    let from = |flag: &str, key: &str| needed("vps worker", flag, key);
    if args.coordinator.is_none() {
        bail!(from("--coordinator ADDR", "coordinator"));
    }
    check_identity(&args.identity, from)
}

/// `vps coordinator`: merges `--config FILE` (when given) under the command-line flags of
/// `matches` (the coordinator subcommand's), then checks that the required settings are there.
pub fn resolve_coordinator(args: &mut CoordinatorArgs, matches: &ArgMatches) -> Result<()> {
    if let Some(path) = args.config.clone() {
        let f = load_coordinator(&path)?;
        let seconds = checked(&path, "seconds", f.seconds, vps_app::limits::parse_seconds)?;
        let threads = checked(&path, "threads", f.threads, vps_app::limits::parse_count)?;
        // As in a scene file: a number is metres, a string needs a unit.
        let key = "voxel_size";
        let voxel_size = match f.voxel_size {
            None => None,
            Some(toml::Value::String(s)) => checked(&path, key, Some(s), parse_length_string)?,
            Some(toml::Value::Float(v)) => checked(&path, key, Some(v), parse_length)?,
            Some(toml::Value::Integer(v)) => checked(&path, key, Some(v), parse_length)?,
            Some(other) => bail!(
                "{}: `voxel_size` = {other}: expected metres or a length with a unit (\"5mm\")",
                path.display()
            ),
        };
        let s = &mut args.session;
        let listen = checked(&path, "listen", f.listen, vps_app::limits::parse_ip_port)?;
        take(matches, "listen", &mut args.listen, listen);
        take_identity(matches, &mut args.identity, &path, f.cert, f.key, f.pins);
        let workers = checked(&path, "workers", f.workers, vps_app::limits::parse_workers)?;
        take(matches, "workers", &mut args.workers, workers);
        let join_wait = checked(
            &path,
            "join_wait",
            f.join_wait,
            vps_app::limits::parse_join_wait,
        )?;
        take(matches, "join_wait", &mut args.join_wait, join_wait);
        let scene = f.scene.map(|v| scene_beside(&path, v));
        take(matches, "scene", &mut s.scene.scene, scene);
        take(matches, "no_cache", &mut s.scene.no_cache, f.no_cache);
        let device = f.device.map(|v| Some(device_beside(&path, v)));
        take(matches, "device", &mut s.device, device);
        let haptic = f.haptic.map(|p| Some(beside(&path, p)));
        take(matches, "haptic", &mut s.haptic, haptic);
        take(
            matches,
            "voxel_size",
            &mut s.sizes.voxel_size,
            voxel_size.map(Some),
        );
        take(matches, "seconds", &mut s.sizes.seconds, seconds.map(Some));
        take(matches, "threads", &mut s.sizes.threads, threads);
        let record = f.record.map(|p| Some(beside(&path, p)));
        take(matches, "record", &mut s.record, record);
        let report = f.report.map(|p| Some(beside(&path, p)));
        take(matches, "report", &mut s.report, report);
        take(matches, "json", &mut s.json, f.json);
        take(matches, "view", &mut s.view, f.view.map(Some));
        let g = &mut args.gather;
        take(matches, "equal_shares", &mut g.equal_shares, f.equal_shares);
        take(matches, "spin_us", &mut g.spin_us, f.spin_us);
        take(
            matches,
            "max_stale_frames",
            &mut g.max_stale_frames,
            f.max_stale_frames,
        );
    }
    let from = |flag: &str, key: &str| needed("vps coordinator", flag, key);
    check_identity(&args.identity, from)
}

/// The error for a required setting given neither as a flag nor in the config file.
fn needed(command: &str, flag: &str, key: &str) -> String {
    format!("{command}: give {flag}, or `{key}` in the --config file")
}

/// Sets the identity's certificate, key and pins to a config file's `cert`, `key` and `pins`
/// (relative paths taken from the directory of `config`, the file)
/// where the command line did not give `--cert`, `--key` or `--pin`.
fn take_identity(
    matches: &ArgMatches,
    identity: &mut IdentityArgs,
    config: &Path,
    cert: Option<PathBuf>,
    key: Option<PathBuf>,
    pins: Option<Vec<PathBuf>>,
) {
    let cert = cert.map(|p| Some(beside(config, p)));
    let key = key.map(|p| Some(beside(config, p)));
    take(matches, "cert", &mut identity.cert, cert);
    take(matches, "key", &mut identity.key, key);
    take(matches, "pin", &mut identity.pin, all_beside(config, pins));
}

/// A service needs its certificate, its key and at least one pinned certificate.
fn check_identity(identity: &IdentityArgs, from: impl Fn(&str, &str) -> String) -> Result<()> {
    if identity.cert.is_none() {
        bail!(from("--cert FILE", "cert"));
    }
    if identity.key.is_none() {
        bail!(from("--key FILE", "key"));
    }
    if identity.pin.is_empty() {
        bail!(from("--pin FILE (repeatable)", "pins"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::{Cli, Command};
    use anyhow::Context;
    use clap::{CommandFactory, FromArgMatches};

    fn repo(path: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
    }

    /// Parses a command line the way `main` does and resolves its config file.
    fn parsed(argv: &[&str]) -> Result<Command> {
        let matches = Cli::command().try_get_matches_from(argv)?;
        let mut cli = Cli::from_arg_matches(&matches)?;
        let (name, sub) = matches.subcommand().context("a subcommand")?;
        match (&mut cli.command, name) {
            (Command::Coordinator(args), "coordinator") => resolve_coordinator(args, sub)?,
            (Command::Worker(args), "worker") => resolve_worker(args, sub)?,
            _ => bail!("not a service command"),
        }
        Ok(cli.command)
    }

    /// `vps SERVICE --config CONFIG FLAGS...`, parsed and resolved.
    fn with_config(service: &str, config: &Path, flags: &[&str]) -> Result<Command> {
        let config = config.to_str().unwrap();
        let argv: Vec<&str> = ["vps", service, "--config", config]
            .iter()
            .chain(flags)
            .copied()
            .collect();
        parsed(&argv)
    }

    /// [`with_config`] for `vps coordinator`, which must succeed.
    fn coordinator(config: &Path, flags: &[&str]) -> CoordinatorArgs {
        match with_config("coordinator", config, flags).unwrap() {
            Command::Coordinator(args) => args,
            _ => panic!("not a coordinator"),
        }
    }

    /// [`with_config`] for `vps worker`, which must succeed.
    fn worker(config: &Path, flags: &[&str]) -> WorkerArgs {
        match with_config("worker", config, flags).unwrap() {
            Command::Worker(args) => args,
            _ => panic!("not a worker"),
        }
    }

    /// Writes `c.toml` in `dir`: a coordinator identity (`cert`, `key`, `pins`) and `rest`.
    fn coordinator_file(dir: &Path, rest: &str) -> PathBuf {
        let path = dir.join("c.toml");
        let text = format!("cert = \"c\"\nkey = \"k\"\npins = [\"p\"]\n{rest}");
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn the_committed_configs_load() {
        let c = load_coordinator(&repo("configs/coordinator.toml")).unwrap();
        assert_eq!(c.listen.as_deref(), Some("0.0.0.0:7800"));
        assert_eq!(c.workers, Some(2));
        assert_eq!(c.pins, Some(vec![PathBuf::from("/etc/vps/pins")]));
        let w = load_worker(&repo("configs/worker.toml")).unwrap();
        assert_eq!(w.coordinator.as_deref(), Some("10.77.0.1:7800"));
        assert_eq!(w.cache, Some(PathBuf::from("/var/cache/vps")));

        let args = coordinator(&repo("configs/coordinator.toml"), &[]);
        assert_eq!(args.workers, 2);
        // Left to the scene: a voxel size here would override the scene file a user names in
        // `scene` (a 1 mm scene ran at 5 mm).
        assert_eq!(args.session.sizes.voxel_size, None);
        assert_eq!(args.gather.spin_us, 100);
        assert_eq!(
            args.identity.cert,
            Some(PathBuf::from("/etc/vps/coordinator.crt"))
        );
        let args = worker(&repo("configs/worker.toml"), &[]);
        assert_eq!(
            args.identity.key,
            Some(PathBuf::from("/etc/vps/worker.key"))
        );
    }

    #[test]
    fn an_unknown_key_names_the_file_and_the_key() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("coordinator.toml");
        std::fs::write(&path, "workers = 2\nspin_usec = 100\n").unwrap();
        let err = load_coordinator(&path).unwrap_err().to_string();
        assert!(
            err.contains(&path.display().to_string()) && err.contains("spin_usec"),
            "{err}"
        );
        std::fs::write(&path, "coordinator = \"10.0.0.1:7800\"\nthreadz = 2\n").unwrap();
        let err = load_worker(&path).unwrap_err().to_string();
        assert!(
            err.contains(&path.display().to_string()) && err.contains("threadz"),
            "{err}"
        );
    }

    #[test]
    fn a_bad_value_names_the_file_and_the_key() {
        let dir = tempfile::tempdir().unwrap();
        let path = coordinator_file(dir.path(), "seconds = -1\n");
        let err = with_config("coordinator", &path, &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(&path.display().to_string()) && err.contains("seconds"),
            "{err}"
        );
    }

    /// The committed systemd units: each `ExecStart` is a command line this binary accepts, its
    /// config file is the one deploy/README.md installs, and both units give vps a writable cache
    /// directory (the coordinator's had none: the `vps` user has no home, so the scene was
    /// voxelized at every start).
    #[test]
    fn the_systemd_units_run_real_command_lines_with_a_cache() {
        for (unit, command, config) in [
            (
                "vps-coordinator.service",
                "coordinator",
                "/etc/vps/coordinator.toml",
            ),
            ("vps-worker.service", "worker", "/etc/vps/worker.toml"),
        ] {
            let text = std::fs::read_to_string(repo(&format!("deploy/systemd/{unit}"))).unwrap();
            let value = |key: &str| {
                text.lines()
                    .find_map(|l| l.strip_prefix(key)?.strip_prefix('='))
                    .unwrap_or_else(|| panic!("{unit}: no {key}"))
                    .to_string()
            };
            let exec = value("ExecStart");
            let argv: Vec<&str> = exec.split_whitespace().collect();
            assert_eq!(argv[..2], ["/usr/local/bin/vps", command], "{unit}");
            assert_eq!(argv[2..], ["--config", config], "{unit}");
            Cli::command()
                .try_get_matches_from(&argv)
                .unwrap_or_else(|e| panic!("{unit}: {e}"));
            assert_eq!(value("CacheDirectory"), "vps", "{unit}");
        }
        let coordinator =
            std::fs::read_to_string(repo("deploy/systemd/vps-coordinator.service")).unwrap();
        assert!(
            coordinator.contains("\nEnvironment=VPS_CACHE_DIR=/var/cache/vps\n"),
            "the coordinator's voxmap cache is not pointed at its CacheDirectory"
        );
        // A worker exits 1 on a configuration error (unknown key, unreadable or mismatched key:
        // tests/service_mistakes.rs) and 2 when refused for good; restarting cures neither.
        let worker = std::fs::read_to_string(repo("deploy/systemd/vps-worker.service")).unwrap();
        assert!(
            worker.contains("\nRestartPreventExitStatus=1 2\n"),
            "the worker unit restarts a worker whose configuration is wrong"
        );
    }

    #[test]
    fn a_voxel_size_with_a_unit_is_read_from_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = coordinator_file(dir.path(), "voxel_size = \"2mm\"\n");
        let args = coordinator(&path, &[]);
        assert_eq!(args.session.sizes.voxel_size, Some(0.002));
        // A string without a unit is refused, as in a scene file (it ran as 5 m voxels).
        let path = coordinator_file(dir.path(), "voxel_size = \"5\"\n");
        let err = with_config("coordinator", &path, &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("`voxel_size`") && err.contains("\"5\" has no unit"),
            "{err}"
        );
    }

    #[test]
    fn a_flag_overrides_the_file() {
        let args = coordinator(
            &repo("configs/coordinator.toml"),
            &["--workers", "5", "--spin-us", "7", "--pin", "/tmp/a.crt"],
        );
        assert_eq!(args.workers, 5);
        assert_eq!(args.gather.spin_us, 7);
        assert_eq!(args.identity.pin, vec![PathBuf::from("/tmp/a.crt")]);
        // Keys not overridden still come from the file.
        assert_eq!(args.gather.max_stale_frames, 3);
        let args = worker(
            &repo("configs/worker.toml"),
            &["--coordinator", "127.0.0.1:9"],
        );
        assert_eq!(args.coordinator, Some("127.0.0.1:9".parse().unwrap()));
        assert_eq!(args.cache, Some(PathBuf::from("/var/cache/vps")));
    }

    #[test]
    fn without_a_file_the_identity_flags_are_required() {
        let err = parsed(&["vps", "worker", "--coordinator", "127.0.0.1:9"])
            .unwrap_err()
            .to_string();
        assert!(err.contains("--cert") && err.contains("`cert`"), "{err}");
    }

    #[test]
    fn relative_paths_in_a_file_are_taken_from_its_directory() {
        let dir = tempfile::tempdir().unwrap();
        let etc = dir.path().join("etc");
        std::fs::create_dir(&etc).unwrap();
        let worker_toml = etc.join("worker.toml");
        std::fs::write(
            &worker_toml,
            "coordinator = \"127.0.0.1:7800\"\ncert = \"worker.crt\"\nkey = \"keys/worker.key\"\n\
             pins = [\"pins\", \"/abs/c.crt\"]\ncache = \"../cache\"\n",
        )
        .unwrap();
        let args = worker(&worker_toml, &[]);
        assert_eq!(args.identity.cert, Some(etc.join("worker.crt")));
        assert_eq!(args.identity.key, Some(etc.join("keys/worker.key")));
        assert_eq!(
            args.identity.pin,
            vec![etc.join("pins"), PathBuf::from("/abs/c.crt")]
        );
        assert_eq!(args.cache, Some(etc.join("../cache")));

        let coordinator_toml = etc.join("coordinator.toml");
        std::fs::write(
            &coordinator_toml,
            "cert = \"c.crt\"\nkey = \"c.key\"\npins = [\"pins\"]\nscene = \"scenes/bay.toml\"\n\
             device = \"replay:traces/t.jsonl\"\nhaptic = \"haptic.toml\"\n\
             record = \"out/trace.jsonl\"\nreport = \"/var/lib/vps/report.json\"\n",
        )
        .unwrap();
        // A flag keeps its own meaning: relative to the working directory.
        let args = coordinator(&coordinator_toml, &["--key", "here.key"]);
        assert_eq!(args.identity.cert, Some(etc.join("c.crt")));
        assert_eq!(args.identity.key, Some(PathBuf::from("here.key")));
        assert_eq!(args.identity.pin, vec![etc.join("pins")]);
        let s = &args.session;
        assert_eq!(
            s.scene.scene,
            etc.join("scenes/bay.toml").display().to_string()
        );
        let replay = format!("replay:{}", etc.join("traces/t.jsonl").display());
        assert_eq!(s.device.as_deref(), Some(replay.as_str()));
        assert_eq!(s.haptic, Some(etc.join("haptic.toml")));
        assert_eq!(s.record, Some(etc.join("out/trace.jsonl")));
        assert_eq!(s.report, Some(PathBuf::from("/var/lib/vps/report.json")));

        // builtin: scenes and other devices are not paths.
        std::fs::write(
            &coordinator_toml,
            "cert = \"c.crt\"\nkey = \"c.key\"\npins = [\"p.crt\"]\nscene = \"builtin:bay-teapot\"\ndevice = \"bridge:127.0.0.1:7700\"\n",
        )
        .unwrap();
        let args = coordinator(&coordinator_toml, &[]);
        assert_eq!(args.session.scene.scene, "builtin:bay-teapot");
        assert_eq!(
            args.session.device.as_deref(),
            Some("bridge:127.0.0.1:7700")
        );
    }

    #[test]
    fn a_host_name_for_the_coordinator_is_refused_saying_to_give_an_ip() {
        let dir = tempfile::tempdir().unwrap();
        let worker = dir.path().join("worker.toml");
        std::fs::write(
            &worker,
            "coordinator = \"coord.lan:7800\"\ncert = \"w.crt\"\nkey = \"w.key\"\npins = [\"c.crt\"]\n",
        )
        .unwrap();
        let err = with_config("worker", &worker, &[]).unwrap_err().to_string();
        assert!(
            err.contains(&format!(
                "{}: `coordinator`: `coord.lan:7800` names a host: give its IP address and port",
                worker.display()
            )),
            "{err}"
        );
        let err = parsed(&["vps", "worker", "--coordinator", "coord.lan:7800"])
            .unwrap_err()
            .to_string();
        assert!(err.contains("host names are not resolved"), "{err}");
        let coordinator = dir.path().join("coordinator.toml");
        std::fs::write(&coordinator, "listen = \"7800\"\n").unwrap();
        let err = with_config("coordinator", &coordinator, &[])
            .unwrap_err()
            .to_string();
        assert!(err.contains("`listen`: `7800` is not IP:port"), "{err}");
        assert_eq!(
            vps_app::limits::parse_ip_port("[::1]:7800"),
            Ok("[::1]:7800".parse().unwrap())
        );
    }
}
