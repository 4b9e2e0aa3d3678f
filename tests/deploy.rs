//! `vps deploy init` and the one fingerprint convention, through the real binary: a loopback
//! layout runs a coordinator and two workers as written (no file edited), it refuses to overwrite
//! and names bad input; `vps cert`'s fingerprint is the SHA-256 of the certificate's DER, computed
//! here independently (the PEM decoded by this file, hashed by `ring`), and what openssl prints.
//!
//! Nothing here depends on timing: every wait is bounded by a generous deadline only.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;
use vps_testkit::process::{free_udp_port, stderr, WatchedProcess};

const DEADLINE: Duration = Duration::from_secs(240);

/// Runs `vps ARGS` to its end, with no `RUST_LOG`.
fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(args)
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .output()
        .expect("run vps")
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Starts a command line written by `vps deploy init` (`vps SUBCOMMAND ARGS...`, paths without
/// spaces) with the real binary, `extra` arguments appended, the voxmap cache in `cache`.
fn start_written(label: &str, command: &str, extra: &[&str], cache: &Path) -> WatchedProcess {
    let mut words = command.split_whitespace();
    assert_eq!(words.next(), Some("vps"), "{command}");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vps"));
    cmd.args(words)
        .args(extra)
        .env("VPS_CACHE_DIR", cache)
        .env_remove("RUST_LOG");
    WatchedProcess::spawn(cmd, label, DEADLINE)
}

#[cfg(unix)]
fn mode(path: &Path) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(path).unwrap().permissions().mode() & 0o777
}

#[test]
fn a_loopback_layout_runs_a_coordinator_and_two_workers_as_written() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("lab");
    let port = free_udp_port().to_string();
    let out_text = out_dir.to_string_lossy().into_owned();
    let init = ["deploy", "init", "--loopback", "2", "--port", &port];
    let out = run(&[&init[..], &["-o", &out_text, "--json"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    let layout: serde_json::Value = serde_json::from_slice(&out.stdout).expect("--json is JSON");
    let hosts = layout["hosts"].as_array().unwrap();
    assert_eq!(hosts.len(), 3, "{layout}");
    let dial = format!("127.0.0.1:{port}");
    assert_eq!(layout["coordinator_address"], dial.as_str());
    assert_eq!(layout["listen"], dial.as_str());

    // One folder per host: its own key (0600) and certificate, the peers' certificates pinned.
    let readme = std::fs::read_to_string(out_dir.join("README.txt")).unwrap();
    for host in hosts {
        let name = host["name"].as_str().unwrap();
        let folder = out_dir.join(name);
        assert!(folder.join(format!("{name}.crt")).is_file());
        #[cfg(unix)]
        assert_eq!(mode(&folder.join(format!("{name}.key"))), 0o600, "{name}");
        let pins: Vec<String> = std::fs::read_dir(folder.join("pins"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        let expected = if host["role"] == "coordinator" { 2 } else { 1 };
        assert_eq!(pins.len(), expected, "{name}: {pins:?}");
        assert!(pins.iter().all(|p| !p.ends_with(".key")), "{pins:?}");
        // README.txt gives the command and the fingerprint of each host.
        let command = host["command"].as_str().unwrap();
        assert!(readme.contains(command), "{command} not in\n{readme}");
        assert!(readme.contains(host["fingerprint"].as_str().unwrap()));
    }
    let worker_pins: Vec<PathBuf> = std::fs::read_dir(out_dir.join("worker-1/pins"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(
        std::fs::read(&worker_pins[0]).unwrap(),
        std::fs::read(out_dir.join("coordinator/coordinator.crt")).unwrap(),
        "a worker pins its coordinator's certificate"
    );

    // Run it from the written commands alone: the workers first, then a 2 s coordinator session.
    let cache = tmp.path().join("voxmap-cache");
    let mut workers: Vec<WatchedProcess> = hosts[1..]
        .iter()
        .map(|h| {
            let label = h["name"].as_str().unwrap();
            start_written(label, h["command"].as_str().unwrap(), &[], &cache)
        })
        .collect();
    let report = tmp.path().join("report.json");
    let report_text = report.to_string_lossy().into_owned();
    let mut coordinator = start_written(
        "coordinator",
        hosts[0]["command"].as_str().unwrap(),
        &["--seconds", "2", "--report", &report_text],
        &cache,
    );
    assert_eq!(coordinator.wait_exit().code(), Some(0));
    for worker in &workers {
        assert_eq!(worker.count(&format!("joined {dial}")), 1);
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["complete"], true, "{report}");
    let peers = report["cluster"]["peers"]
        .as_array()
        .expect("per-worker report");
    assert_eq!(peers.len(), 2, "both workers joined: {report}");
    for peer in peers {
        assert_eq!(peer["scene_sent"], true, "{peer}");
    }
    assert_ne!(peers[0]["id"], peers[1]["id"]);
    // The workers stay for the next coordinator until told to stop.
    for worker in &mut workers {
        assert!(worker.is_running(), "a worker exited with its coordinator");
        worker.signal("TERM");
        assert_eq!(worker.wait_exit().code(), Some(0));
    }
}

#[test]
fn deploy_init_never_overwrites_and_names_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("lan");
    let d = dir.to_string_lossy().into_owned();
    let lan = [
        "deploy",
        "init",
        "--coordinator",
        "lab-pc=192.168.1.10",
        "--worker",
        "node-1=192.168.1.11",
        "--worker",
        "node-2",
        "-o",
        &d,
    ];
    let out = run(&lan);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    assert!(
        !text.trim_start().starts_with('{'),
        "text without --json: {text}"
    );
    assert!(text.contains("a coordinator and 2 worker(s)"), "{text}");
    let coordinator = std::fs::read_to_string(dir.join("lab-pc/coordinator.toml")).unwrap();
    assert!(
        coordinator.contains("listen = \"0.0.0.0:7800\""),
        "{coordinator}"
    );
    assert!(coordinator.contains("workers = 2"), "{coordinator}");
    let worker = std::fs::read_to_string(dir.join("node-2/worker.toml")).unwrap();
    assert!(
        worker.contains("coordinator = \"192.168.1.10:7800\""),
        "{worker}"
    );
    let readme = std::fs::read_to_string(dir.join("README.txt")).unwrap();
    assert!(readme.contains("on node-1 (192.168.1.11)"), "{readme}");
    assert!(readme.contains("openssl x509 -in FILE -noout -fingerprint -sha256"));

    // Again into the same folder: refused, naming a file, and nothing is replaced.
    let key = std::fs::read(dir.join("lab-pc/lab-pc.key")).unwrap();
    let out = run(&lan);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(
        err.contains("exists already") && err.contains("never overwrites"),
        "{err}"
    );
    assert_eq!(std::fs::read(dir.join("lab-pc/lab-pc.key")).unwrap(), key);

    // Bad input names the flag and what is allowed.
    let other = tmp.path().join("other").to_string_lossy().into_owned();
    for (args, expected) in [
        (
            vec!["--coordinator", "lab-pc", "--worker", "w"],
            "give NAME=IP[:PORT]",
        ),
        (
            vec!["--coordinator", "c=lab.local", "--worker", "w"],
            "names a host",
        ),
        (
            vec!["--coordinator", "c=10.0.0.1", "--worker", "c"],
            "given twice",
        ),
        (
            vec!["--coordinator", "c=10.0.0.1", "--worker", "../w"],
            "a host name is 1 to 64",
        ),
        (vec!["--loopback", "0"], "allowed 1..=64"),
        (vec!["--loopback", "2", "--port", "0"], "1..=65535"),
    ] {
        let full = [&["deploy", "init", "-o", &other][..], &args[..]].concat();
        let out = run(&full);
        let err = stderr(&out);
        assert!(!out.status.success(), "{args:?}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(!Path::new(&other).exists(), "nothing written for bad input");
}

/// Standard base64 (the PEM body), decoded here so the test does not use the code under test.
fn base64_decode(text: &str) -> Vec<u8> {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut bits = 0u32;
    let mut count = 0;
    let mut out = Vec::new();
    for c in text
        .bytes()
        .filter(|c| !c.is_ascii_whitespace() && *c != b'=')
    {
        let v = ALPHABET.iter().position(|a| *a == c).expect("base64") as u32;
        bits = (bits << 6) | v;
        count += 6;
        if count >= 8 {
            count -= 8;
            out.push((bits >> count) as u8);
        }
    }
    out
}

#[test]
fn vps_cert_prints_the_sha256_of_the_certificates_der_as_openssl_does() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path().to_string_lossy().into_owned();
    let out = run(&["cert", "--out", &d, "--name", "node-7"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    let printed = text
        .lines()
        .find_map(|l| l.strip_prefix("sha256"))
        .expect("a sha256 line")
        .trim()
        .to_string();
    let crt = tmp.path().join("node-7.crt");
    let pem = std::fs::read_to_string(&crt).unwrap();
    let body: String = pem
        .lines()
        .skip_while(|l| !l.starts_with("-----BEGIN CERTIFICATE-----"))
        .skip(1)
        .take_while(|l| !l.starts_with("-----END"))
        .collect();
    let der = base64_decode(&body);
    let digest = ring::digest::digest(&ring::digest::SHA256, &der);
    let expected: Vec<String> = digest.as_ref().iter().map(|b| format!("{b:02X}")).collect();
    assert_eq!(printed, expected.join(":"), "{text}");
    // Not the digest of the PEM file (what `sha256sum` gives).
    let of_pem = ring::digest::digest(&ring::digest::SHA256, pem.as_bytes());
    let of_pem: String = of_pem.as_ref().iter().map(|b| format!("{b:02x}")).collect();
    assert!(!printed.replace(':', "").eq_ignore_ascii_case(&of_pem));
    assert!(
        text.contains(&format!(
            "openssl x509 -in {} -noout -fingerprint -sha256",
            crt.display()
        )),
        "{text}"
    );

    // openssl itself, where it is installed.
    let openssl = Command::new("openssl")
        .args([
            "x509",
            "-in",
            &crt.to_string_lossy(),
            "-noout",
            "-fingerprint",
            "-sha256",
        ])
        .output();
    match openssl {
        Ok(o) if o.status.success() => {
            let line = String::from_utf8_lossy(&o.stdout);
            let digits = line.trim().rsplit('=').next().unwrap().to_string();
            assert_eq!(digits, printed, "openssl printed {line}");
        }
        _ => eprintln!("openssl not runnable here: its fingerprint was not compared (the independent DER hash above was)"),
    }
}
