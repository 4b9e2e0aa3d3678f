//! `vps deploy init`: a ready cluster layout for a list of hosts (or a loopback rehearsal) in a
//! new folder, one sub-folder per host.
//!
//! Each host's folder is what its `/etc/vps` holds: its own certificate and private key (made as
//! `vps cert` makes them, named after the host; the key mode 0600), `pins/` with the certificates
//! of the peers it admits (a coordinator its workers', a worker its coordinator's), and its
//! `coordinator.toml` or `worker.toml` in the format of configs/ (relative paths, so the folder
//! works wherever it is copied: [`crate::service_files`] takes them from the file's directory).
//! `README.txt` beside the folders says which command to run on which host. Nothing is ever
//! overwritten: every path is checked before the first file is written, and each file is created
//! new.

use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::fmt::Write as _;
use std::io::Write as _;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::path::{Path, PathBuf};
use vps_app::limits::MAX_WORKERS;
use vps_app::output::print_summary;
use vps_cluster::tls::{fingerprint, load_cert, FINGERPRINT_COMMAND};

/// What `vps deploy init` is asked: the hosts (or a one-host rehearsal), the port and the
/// folder to write. Ranges are checked here ([`init`]) and by the command line's parsers.
#[derive(Debug, Clone, Default)]
pub struct DeployRequest {
    /// The coordinator host, `NAME=IP[:PORT]`: the address its workers dial.
    pub coordinator: Option<String>,
    /// The worker hosts, each `NAME` or `NAME=ADDR`.
    pub worker: Vec<String>,
    /// A one-host rehearsal instead: a coordinator on 127.0.0.1 and this many workers (1..=64).
    pub loopback: Option<usize>,
    /// The coordinator's UDP port where `coordinator` gives none, and with `loopback`.
    pub port: u16,
    /// The folder to write (created; the files in it must not exist yet).
    pub out: PathBuf,
    /// Print what was written as JSON.
    pub json: bool,
}

/// The longest host name (it names a folder and a certificate).
const MAX_NAME_LEN: usize = 64;

/// What a host does in the cluster.
#[derive(Serialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// The host with the device, which listens for its workers.
    Coordinator,
    /// A compute host, which dials the coordinator.
    Worker,
}

impl Role {
    /// The name of the host's config file, and of the `vps` subcommand that reads it.
    fn name(self) -> &'static str {
        match self {
            Role::Coordinator => "coordinator",
            Role::Worker => "worker",
        }
    }
}

/// One host as asked for on the command line.
#[derive(Debug, Clone)]
struct HostPlan {
    name: String,
    role: Role,
    /// A worker's `=ADDR`, for README.txt only.
    address: Option<String>,
}

/// The layout asked for: who the hosts are and where the coordinator is.
#[derive(Debug)]
struct Plan {
    loopback: bool,
    /// The coordinator first, then the workers in the order given.
    hosts: Vec<HostPlan>,
    /// The address the workers dial.
    dial: SocketAddr,
    /// The address the coordinator listens on: `dial` on loopback, else the unspecified address
    /// of its family at its port.
    listen: SocketAddr,
}

/// One host of the written layout.
#[derive(Serialize, Debug)]
pub struct DeployedHost {
    /// The host's name (its folder's and its certificate's).
    pub name: String,
    /// Coordinator or worker.
    pub role: Role,
    /// Its folder.
    pub folder: PathBuf,
    /// Its config file (`coordinator.toml` or `worker.toml`).
    pub config: PathBuf,
    /// Its certificate (PEM).
    pub cert: PathBuf,
    /// Its private key (PEM, mode 0600).
    pub key: PathBuf,
    /// Its certificate's SHA-256 fingerprint (`vps_cluster::tls::fingerprint`).
    pub fingerprint: String,
    /// A worker's address as given (`--worker NAME=ADDR`); the coordinator's, the one its workers
    /// dial.
    pub address: Option<String>,
    /// The command that runs it from this folder as written (on loopback, from anywhere here).
    pub command: String,
}

/// What `vps deploy init` wrote.
#[derive(Serialize, Debug)]
pub struct DeployLayout {
    /// The folder written (absolute).
    pub dir: PathBuf,
    /// Whether it is a one-host loopback rehearsal.
    pub loopback: bool,
    /// The address the workers dial.
    pub coordinator_address: SocketAddr,
    /// The address the coordinator listens on.
    pub listen: SocketAddr,
    /// The coordinator first, then the workers.
    pub hosts: Vec<DeployedHost>,
    /// The README.txt saying which command to run on which host.
    pub readme: PathBuf,
}

impl std::fmt::Display for DeployLayout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let workers = self.hosts.len() - 1;
        let kind = if self.loopback {
            "a loopback layout (every host on this machine)"
        } else {
            "a cluster layout"
        };
        writeln!(
            f,
            "vps deploy init: wrote {kind}, a coordinator and {workers} worker(s), into {}",
            self.dir.display()
        )?;
        for host in &self.hosts {
            let place = match host.role {
                Role::Coordinator => format!(
                    "listens on {}, workers dial {}",
                    self.listen, self.coordinator_address
                ),
                Role::Worker => format!("dials {}", self.coordinator_address),
            };
            writeln!(
                f,
                "  {:<11}  {:<16}  {place}",
                host.role.name(),
                format!("{}/", host.name)
            )?;
            writeln!(f, "               sha256 {}", host.fingerprint)?;
        }
        writeln!(
            f,
            "Fingerprints: the SHA-256 of each certificate's DER; `{FINGERPRINT_COMMAND}` prints the same."
        )?;
        if self.loopback {
            writeln!(
                f,
                "Run, each in its own terminal, the workers first (the coordinator waits 20 s for them):"
            )?;
            for host in self.hosts.iter().skip(1).chain(self.hosts.first()) {
                writeln!(f, "  {}", host.command)?;
            }
        } else {
            writeln!(
                f,
                "Copy each folder to its own host only; {} says what to run where.",
                self.readme.display()
            )?;
        }
        write!(f, "Details: {}", self.readme.display())
    }
}

/// `vps deploy init`: writes the layout of [`DeployRequest`] into its `--out` folder and prints
/// what it wrote (text, or JSON with `--json`).
pub fn init(args: &DeployRequest) -> Result<()> {
    let plan = plan(args)?;
    let layout = write_layout(&plan, &args.out)?;
    print_summary(&layout, args.json)
}

/// Reads the hosts of the command line.
fn plan(args: &DeployRequest) -> Result<Plan> {
    if let Some(n) = args.loopback {
        let dial = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), args.port);
        let mut hosts = vec![HostPlan {
            name: "coordinator".into(),
            role: Role::Coordinator,
            address: None,
        }];
        hosts.extend((1..=n).map(|k| HostPlan {
            name: format!("worker-{k}"),
            role: Role::Worker,
            address: None,
        }));
        return Ok(Plan {
            loopback: true,
            hosts,
            dial,
            listen: dial,
        });
    }
    let Some(coordinator) = &args.coordinator else {
        bail!("vps deploy init: give --coordinator NAME=IP[:PORT] and --worker NAME for each worker, or --loopback N");
    };
    let (name, dial) = parse_coordinator(coordinator, args.port)?;
    if args.worker.is_empty() || args.worker.len() > MAX_WORKERS {
        bail!(
            "vps deploy init: {} --worker given; allowed 1..={MAX_WORKERS} (one class of the shell at least each)",
            args.worker.len()
        );
    }
    let mut hosts = vec![HostPlan {
        name,
        role: Role::Coordinator,
        address: Some(dial.to_string()),
    }];
    for text in &args.worker {
        let (name, address) = match text.split_once('=') {
            Some((name, address)) => {
                let address = address.trim();
                if address.is_empty() {
                    bail!(
                        "--worker `{text}`: the address after `=` is empty; give NAME or NAME=ADDR"
                    );
                }
                (name, Some(address.to_string()))
            }
            None => (text.as_str(), None),
        };
        check_name("--worker", name)?;
        hosts.push(HostPlan {
            name: name.to_string(),
            role: Role::Worker,
            address,
        });
    }
    check_distinct(&hosts)?;
    let listen = if dial.ip().is_loopback() {
        dial
    } else if dial.is_ipv4() {
        SocketAddr::new(IpAddr::V4(Ipv4Addr::UNSPECIFIED), dial.port())
    } else {
        SocketAddr::new(IpAddr::V6(Ipv6Addr::UNSPECIFIED), dial.port())
    };
    Ok(Plan {
        loopback: false,
        hosts,
        dial,
        listen,
    })
}

/// `--coordinator NAME=IP[:PORT]`: the name and the address the workers dial (`port` where the
/// text gives none).
fn parse_coordinator(text: &str, port: u16) -> Result<(String, SocketAddr)> {
    let Some((name, address)) = text.split_once('=') else {
        bail!("--coordinator `{text}`: give NAME=IP[:PORT], the name and the address its workers dial (e.g. lab-pc=192.168.1.10 or lab-pc=192.168.1.10:7800)");
    };
    check_name("--coordinator", name)?;
    let address = address.trim();
    let bare = address.trim_start_matches('[').trim_end_matches(']');
    let dial = match (address.parse::<SocketAddr>(), bare.parse::<IpAddr>()) {
        (Ok(dial), _) => dial,
        (_, Ok(ip)) => SocketAddr::new(ip, port),
        _ => {
            let with_port = format!("{address}:{port}");
            let why = vps_app::limits::parse_ip_port(if address.contains(':') {
                address
            } else {
                &with_port
            })
            .err()
            .unwrap_or_else(|| format!("`{address}` is not IP[:PORT]"));
            bail!("--coordinator `{text}`: {why}");
        }
    };
    if dial.port() == 0 {
        bail!("--coordinator `{text}`: port 0; allowed 1..=65535");
    }
    if dial.ip().is_unspecified() {
        bail!("--coordinator `{text}`: {} is no address a worker can dial; give the coordinator's LAN IP", dial.ip());
    }
    Ok((name.to_string(), dial))
}

/// A host name: 1 to [`MAX_NAME_LEN`] letters, digits, `-`, `_` or `.`, not starting with `.`
/// (it names a folder and a certificate).
fn check_name(flag: &str, name: &str) -> Result<()> {
    let ok = !name.is_empty()
        && name.len() <= MAX_NAME_LEN
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.');
    if !ok {
        bail!("{flag} `{name}`: a host name is 1 to {MAX_NAME_LEN} letters, digits, '-', '_' or '.', not starting with '.' (it names the host's folder and certificate)");
    }
    Ok(())
}

/// Every host a name of its own (ignoring case: they name folders), none `README.txt`.
fn check_distinct(hosts: &[HostPlan]) -> Result<()> {
    let mut seen = std::collections::BTreeSet::new();
    for host in hosts {
        let folded = host.name.to_ascii_lowercase();
        if folded == "readme.txt" {
            bail!(
                "host name `{}`: reserved for the layout's README.txt; choose another",
                host.name
            );
        }
        if !seen.insert(folded) {
            bail!("host name `{}` given twice (names are compared ignoring case: each names a folder); give each host its own", host.name);
        }
    }
    Ok(())
}

/// The files of one host, relative to its folder.
fn host_files(plan: &Plan, host: &HostPlan) -> Vec<PathBuf> {
    let mut files = vec![
        PathBuf::from(format!("{}.crt", host.name)),
        PathBuf::from(format!("{}.key", host.name)),
        PathBuf::from(format!("{}.toml", host.role.name())),
    ];
    files
        .extend(peers(plan, host).map(|peer| Path::new("pins").join(format!("{}.crt", peer.name))));
    files
}

/// The hosts `host` pins: a coordinator its workers, a worker its coordinator.
fn peers<'a>(plan: &'a Plan, host: &'a HostPlan) -> impl Iterator<Item = &'a HostPlan> + 'a {
    plan.hosts.iter().filter(move |h| h.role != host.role)
}

/// Writes the layout of `plan` into `dir`, refusing (before writing anything) when any of its
/// files exists already.
fn write_layout(plan: &Plan, dir: &Path) -> Result<DeployLayout> {
    match std::fs::metadata(dir) {
        Ok(m) if !m.is_dir() => bail!(
            "--out {}: exists and is not a folder; give a new folder (or an empty one)",
            dir.display()
        ),
        _ => {}
    }
    let readme = dir.join("README.txt");
    let mut every = vec![readme.clone()];
    for host in &plan.hosts {
        let folder = dir.join(&host.name);
        every.extend(host_files(plan, host).iter().map(|f| folder.join(f)));
    }
    for path in &every {
        if std::fs::symlink_metadata(path).is_ok() {
            bail!(
                "{}: exists already; vps deploy init never overwrites a file (a new certificate would lock out the hosts holding the old one): give a new --out folder, or remove the old layout first",
                path.display()
            );
        }
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating --out {}", dir.display()))?;
    let dir = std::fs::canonicalize(dir).with_context(|| format!("--out {}", dir.display()))?;

    let mut hosts = Vec::new();
    for host in &plan.hosts {
        let folder = dir.join(&host.name);
        let files = vps_cluster::make_cert(&folder, &host.name)?;
        let fingerprint = fingerprint(&load_cert(&files.cert)?);
        let config = folder.join(format!("{}.toml", host.role.name()));
        let command = if plan.loopback {
            format!("vps {} --config {}", host.role.name(), config.display())
        } else {
            format!(
                "vps {} --config /etc/vps/{}.toml",
                host.role.name(),
                host.role.name()
            )
        };
        hosts.push(DeployedHost {
            name: host.name.clone(),
            role: host.role,
            folder,
            config,
            cert: files.cert,
            key: files.key,
            fingerprint,
            address: match host.role {
                Role::Coordinator => Some(plan.dial.to_string()),
                Role::Worker => host.address.clone(),
            },
            command,
        });
    }
    for (host, written) in plan.hosts.iter().zip(&hosts) {
        let pins = written.folder.join("pins");
        std::fs::create_dir_all(&pins).with_context(|| format!("creating {}", pins.display()))?;
        for peer in hosts.iter().filter(|h| h.role != host.role) {
            let pem = std::fs::read(&peer.cert)
                .with_context(|| format!("reading {}", peer.cert.display()))?;
            write_new(&pins.join(format!("{}.crt", peer.name)), &pem)?;
        }
        let text = match host.role {
            Role::Coordinator => coordinator_toml(plan, host),
            Role::Worker => worker_toml(plan, host),
        };
        write_new(&written.config, text.as_bytes())?;
    }
    let layout = DeployLayout {
        dir: dir.clone(),
        loopback: plan.loopback,
        coordinator_address: plan.dial,
        listen: plan.listen,
        hosts,
        readme: dir.join("README.txt"),
    };
    write_new(&layout.readme, readme_text(&layout).as_bytes())?;
    Ok(layout)
}

/// Creates `path` with `bytes`; an existing file is an error naming it (never replaced).
fn write_new(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .and_then(|mut f| f.write_all(bytes))
        .with_context(|| format!("writing {}", path.display()))
}

/// The first lines of both configs.
fn config_header(plan: &Plan, host: &HostPlan) -> String {
    let role = host.role.name();
    format!(
        "# The {role} `{name}` of a vps cluster layout written by `vps deploy init` ({hosts} hosts; the\n\
         # layout's README.txt says what to run where). Read by `vps {role} --config FILE`; every key\n\
         # is the flag of the same name (`vps {role} --help`; configs/{role}.toml in the repository\n\
         # lists every key). Relative paths are this file's folder's, so the folder works wherever it\n\
         # is copied (e.g. to /etc/vps).\n\n",
        name = host.name,
        hosts = plan.hosts.len(),
    )
}

/// The coordinator's `coordinator.toml`.
fn coordinator_toml(plan: &Plan, host: &HostPlan) -> String {
    let workers = plan.hosts.len() - 1;
    let mut text = config_header(plan, host);
    let listen_note = if plan.loopback {
        "this machine's loopback only"
    } else {
        "every interface; its workers dial "
    };
    let dial = if plan.loopback {
        String::new()
    } else {
        plan.dial.to_string()
    };
    let _ = write!(
        text,
        "# UDP (QUIC) address to listen on: {listen_note}{dial}.\n\
         listen = \"{listen}\"\n\n\
         # This coordinator's certificate and private key (keep the key on this host only).\n\
         cert = \"{name}.crt\"\n\
         key = \"{name}.key\"\n\n\
         # The workers' certificates: every *.crt in pins/ is admitted, any other worker refused.\n\
         pins = [\"pins\"]\n\n\
         # Workers to wait for (20 s at most) before the session starts.\n\
         workers = {workers}\n\n\
         # The session: a scene file or builtin:NAME, the device (sim | spacemouse | bridge[:ADDR] |\n\
         # replay:FILE), its length (s), compute threads here.\n\
         scene = \"builtin:bay-teapot\"\n\
         device = \"sim\"\n\
         seconds = 30\n\
         threads = 1\n",
        listen = plan.listen,
        name = host.name,
    );
    text
}

/// A worker's `worker.toml`.
fn worker_toml(plan: &Plan, host: &HostPlan) -> String {
    let mut text = config_header(plan, host);
    let (cache, cache_note, threads) = if plan.loopback {
        (
            "cache",
            "a folder beside this file",
            "# Compute threads: one, as the workers share this machine.\nthreads = 1\n",
        )
    } else {
        (
            "/var/cache/vps",
            "the systemd unit makes /var/cache/vps writable",
            "# Compute threads (left out: one per core).\n# threads = 4\n",
        )
    };
    let _ = write!(
        text,
        "# The coordinator's address (IP:port), which this worker dials.\n\
         coordinator = \"{dial}\"\n\n\
         # This worker's certificate and private key (keep the key on this host only).\n\
         cert = \"{name}.crt\"\n\
         key = \"{name}.key\"\n\n\
         # The coordinator's certificate: every *.crt in pins/ is accepted, any other refused.\n\
         pins = [\"pins\"]\n\n\
         # Scenes received from the coordinator, cached by content hash ({cache_note}).\n\
         cache = \"{cache}\"\n\n\
         {threads}",
        dial = plan.dial,
        name = host.name,
    );
    text
}

/// README.txt: the hosts, their fingerprints, and which command to run on which host.
fn readme_text(layout: &DeployLayout) -> String {
    let mut t = String::new();
    let workers = layout.hosts.len() - 1;
    let _ = writeln!(
        t,
        "A vps cluster layout written by `vps deploy init`: a coordinator and {workers} worker(s).\n"
    );
    let _ = writeln!(
        t,
        "Each folder is one host's: its certificate (NAME.crt) and private key (NAME.key, mode 0600;\n\
         it never leaves that host), pins/ with the certificates of the peers it admits, and its\n\
         config (coordinator.toml or worker.toml). Paths in a config are relative to its folder.\n"
    );
    let _ = writeln!(t, "Hosts:");
    let width = layout
        .hosts
        .iter()
        .map(|h| h.name.len() + 1)
        .max()
        .unwrap_or(0);
    for host in &layout.hosts {
        let place = match (host.role, &host.address) {
            (Role::Coordinator, _) => format!(
                "listens on {}; its workers dial {}",
                layout.listen, layout.coordinator_address
            ),
            (Role::Worker, Some(address)) => {
                format!("at {address}; dials {}", layout.coordinator_address)
            }
            (Role::Worker, None) => format!("dials {}", layout.coordinator_address),
        };
        let folder = format!("{}/", host.name);
        let _ = writeln!(t, "  {folder:<width$}  {:<11}  {place}", host.role.name());
    }
    let _ = writeln!(
        t,
        "\nFingerprints: the SHA-256 of each certificate's DER, as `vps cert` prints it and a\n\
         coordinator logs a refused worker. `{FINGERPRINT_COMMAND}` prints the same\n\
         digits (after `sha256 Fingerprint=`); compare them on both ends after copying. (`sha256sum FILE`\n\
         hashes the PEM text and gives another digest.)"
    );
    for host in &layout.hosts {
        let file = format!("{}.crt", host.name);
        let _ = writeln!(t, "  {file:<w$}  {}", host.fingerprint, w = width + 3);
    }
    if layout.loopback {
        let _ = writeln!(
            t,
            "\nA one-host rehearsal: everything runs on this machine from this folder, as written.\n\
             Run each command in its own terminal, the workers first (a worker waits for its\n\
             coordinator; the coordinator waits 20 s for its workers, then runs a 30 s session with\n\
             the simulated device; add --json for its report as JSON):"
        );
        for host in layout.hosts.iter().skip(1).chain(layout.hosts.first()) {
            let _ = writeln!(t, "  {}", host.command);
        }
        let _ = writeln!(
            t,
            "Stop a worker with Ctrl-C (or SIGTERM); it exits at once."
        );
        return t;
    }
    let coordinator = &layout.hosts[0];
    let _ = writeln!(
        t,
        "\n1. On every host, install vps and make the vps user and /etc/vps (deploy/README.md, section 1).\n\
         2. Copy each folder to its own host only, over a channel you trust (scp -r, a USB stick),\n   \
            and install it as /etc/vps there; e.g. for the coordinator `{name}`:\n     \
              sudo cp -r {name}/. /etc/vps/\n     \
              sudo chgrp vps /etc/vps/{name}.key && sudo chmod 0640 /etc/vps/{name}.key\n   \
            and the same on each worker with its own folder. Then compare the fingerprints above.\n\
         3. Open UDP {port} on `{name}` to the workers (deploy/README.md, section 4); workers only dial out.\n\
         4. Start the workers, then the coordinator (it waits 20 s for its {workers} worker(s)); the
               systemd units are installed as deploy/README.md, section 5 shows:",
        name = coordinator.name,
        port = layout.coordinator_address.port(),
    );
    for host in layout.hosts.iter().skip(1) {
        let at = host
            .address
            .as_deref()
            .map_or(String::new(), |a| format!(" ({a})"));
        let _ = writeln!(
            t,
            "     on {}{at}: sudo systemctl enable --now vps-worker   (or: sudo -u vps {})",
            host.name, host.command
        );
    }
    let _ = writeln!(
        t,
        "     on {}: sudo systemctl start vps-coordinator   (or: sudo -u vps {} --json)",
        coordinator.name, coordinator.command
    );
    let _ = writeln!(
        t,
        "   coordinator.toml runs a 30 s session of builtin:bay-teapot with the simulated device:\n   \
         set its `scene`, `device` and `seconds` for real work."
    );
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coordinator_address_is_an_ip_with_an_optional_port() {
        let (name, dial) = parse_coordinator("lab-pc=192.168.1.10", 7800).unwrap();
        assert_eq!(
            (name.as_str(), dial.to_string().as_str()),
            ("lab-pc", "192.168.1.10:7800")
        );
        let (_, dial) = parse_coordinator("lab=10.0.0.1:7900", 7800).unwrap();
        assert_eq!(dial.to_string(), "10.0.0.1:7900");
        let (_, dial) = parse_coordinator("lab=fe80::1", 7800).unwrap();
        assert_eq!(dial.to_string(), "[fe80::1]:7800");
        let e = parse_coordinator("lab-pc", 7800).unwrap_err().to_string();
        assert!(e.contains("give NAME=IP[:PORT]"), "{e}");
        let e = parse_coordinator("lab=lab-pc.local", 7800)
            .unwrap_err()
            .to_string();
        assert!(e.contains("names a host"), "{e}");
        let e = parse_coordinator("lab=0.0.0.0", 7800)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no address a worker can dial"), "{e}");
        let e = parse_coordinator("../x=10.0.0.1", 7800)
            .unwrap_err()
            .to_string();
        assert!(e.contains("a host name is 1 to 64"), "{e}");
    }

    #[test]
    fn host_names_are_distinct_ignoring_case() {
        let host = |name: &str| HostPlan {
            name: name.into(),
            role: Role::Worker,
            address: None,
        };
        assert!(check_distinct(&[host("a"), host("b")]).is_ok());
        let e = check_distinct(&[host("a"), host("A")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("given twice"), "{e}");
        assert!(check_distinct(&[host("README.txt")]).is_err());
    }
}
