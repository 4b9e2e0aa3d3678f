//! Resources and parameters a user names are bounded, with errors that name the flag or the file
//! and key, and the allowed range (issue 15, finding 6).

use vps_testkit::process::{stderr, Vps};

fn sandbox() -> Vps {
    Vps::new(env!("CARGO_BIN_EXE_vps"))
}

/// Runs `vps ARGS` in a fresh sandbox; asserts that it fails, without a panic, naming each of
/// `wants` on stderr.
fn refused(args: &[&str], wants: &[&str]) {
    let out = sandbox().run(args);
    let stderr = stderr(&out);
    assert!(
        matches!(out.status.code(), Some(c) if c != 0),
        "{args:?} accepted: {stderr}"
    );
    for want in wants {
        assert!(stderr.contains(want), "{args:?}: {want:?} not in: {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn thread_and_worker_counts_are_bounded_by_the_machine() {
    for args in [
        &["run", "--threads", "10000"][..],
        &["demo", "--threads", "10000"],
        &["run", "--threads", "0"],
        &["cluster", "--local-workers", "1000"],
        &["cluster", "--worker-threads", "1000"],
    ] {
        let flag = args[1];
        refused(args, &[flag, "allowed 1..="]);
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let limit = 4 * cores;
    // Each within bounds, the product not.
    let workers = limit.to_string();
    refused(
        &[
            "cluster",
            "--local-workers",
            &workers,
            "--worker-threads",
            "2",
        ],
        &[
            "--local-workers × --worker-threads",
            &format!("at most {limit}"),
        ],
    );
}

/// Issue 36 item 10: `workers = 1000000` was accepted and the coordinator waited for a million
/// workers. On the command line and in the coordinator's config file it is refused at once,
/// naming the flag or the file and key and the range 1..=64 (64 classes, one per worker at least).
#[test]
fn a_coordinators_worker_count_is_bounded_by_the_classes() {
    for workers in ["1000000", "65", "0"] {
        refused(
            &[
                "coordinator",
                "--workers",
                workers,
                "--cert",
                "c",
                "--key",
                "k",
            ],
            &["--workers", "allowed 1..=64"],
        );
    }
    let vps = sandbox();
    let config = vps.dir().join("coordinator.toml");
    std::fs::write(&config, "workers = 1000000\n").unwrap();
    let out = vps.run(&["coordinator", "--config", config.to_str().unwrap()]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("coordinator.toml") && err.contains("`workers`") && err.contains("1..=64"),
        "{err}"
    );
}

#[test]
fn session_lengths_must_be_finite_and_positive() {
    for bad in ["-1", "0", "nan", "inf", "1e300"] {
        let flag = format!("--seconds={bad}");
        for command in ["run", "demo", "record"] {
            let mut args = vec![command, flag.as_str()];
            if command == "record" {
                args.extend(["-o", "/nonexistent/t.jsonl"]);
            }
            refused(&args, &["--seconds", "> 0", "1e7 s"]);
        }
    }
}

#[test]
fn haptic_files_name_the_file_the_key_and_the_range() {
    let vps = sandbox();
    for (name, text, wants) in [
        ("weak.toml", "k_ff = 1e-300\n", ["k_ff", "[1e0, 1e9] N/m"]),
        (
            "slow.toml",
            "dt = 0.002\n",
            ["`dt` = 0.002", "must be 0.001 s"],
        ),
    ] {
        let path = vps.path(name);
        std::fs::write(&path, text).unwrap();
        refused(&["run", "--haptic", &path], &[&path, wants[0], wants[1]]);
    }
}
