//! `vps cluster --local-workers 2` keeps everything but the frame thread off the frame thread's
//! core: the worker processes (every thread of theirs) and the coordinator's network and metrics
//! threads, read from `/proc/<pid>/task/*/status` (`Cpus_allowed_list`) while the session runs,
//! and the run report's `cluster.placement` says so. Skipped on a machine of one core.

use std::collections::BTreeMap;
use std::io::Read;
use std::process::Stdio;
use std::time::Duration;
use vps_testkit::process::Vps;

/// Parses a `Cpus_allowed_list` value such as `0-2,5`.
fn parse_list(list: &str) -> Vec<usize> {
    let mut cores = Vec::new();
    for part in list.trim().split(',').filter(|p| !p.is_empty()) {
        match part.split_once('-') {
            Some((a, b)) => cores.extend(a.parse::<usize>().unwrap()..=b.parse().unwrap()),
            None => cores.push(part.parse().unwrap()),
        }
    }
    cores
}

/// `Cpus_allowed_list` of task `tid` of process `pid` (`None`: gone).
fn allowed(pid: u32, tid: &str) -> Option<Vec<usize>> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/task/{tid}/status")).ok()?;
    let line = status
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))?;
    Some(parse_list(line))
}

/// Every task of `pid`: (thread name, allowed cores).
fn tasks(pid: u32) -> Vec<(String, Vec<usize>)> {
    let Ok(dir) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    dir.flatten()
        .filter_map(|t| {
            let tid = t.file_name().into_string().ok()?;
            let name = std::fs::read_to_string(format!("/proc/{pid}/task/{tid}/comm")).ok()?;
            Some((name.trim().to_string(), allowed(pid, &tid)?))
        })
        .collect()
}

/// The child processes of `pid` (all its tasks' `children` lists).
fn children(pid: u32) -> Vec<u32> {
    let Ok(dir) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    let mut pids: Vec<u32> = dir
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("children")).ok())
        .flat_map(|s| {
            s.split_whitespace()
                .filter_map(|p| p.parse().ok())
                .collect::<Vec<u32>>()
        })
        .collect();
    pids.sort_unstable();
    pids.dedup();
    pids
}

/// Whether process `pid` has exec'd `vps worker`. Between `fork` and `exec` a child still runs
/// the coordinator's image with the forking thread's mask (its own mask is set just before
/// `exec`), so only what a child does after `exec` is judged; once its command line says
/// `worker`, it stays so.
fn is_worker(pid: u32) -> bool {
    std::fs::read(format!("/proc/{pid}/cmdline"))
        .map(|cmdline| cmdline.split(|&b| b == 0).nth(1) == Some(b"worker".as_slice()))
        .unwrap_or(false)
}

fn own_cores() -> Vec<usize> {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    parse_list(
        status
            .lines()
            .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
            .unwrap(),
    )
}

#[test]
fn parse_list_reads_ranges_and_singles() {
    assert_eq!(parse_list("0-2,5\n"), vec![0, 1, 2, 5]);
    assert_eq!(parse_list("3"), vec![3]);
}

#[test]
fn local_workers_and_coordinator_threads_stay_off_the_frame_core() {
    if !std::path::Path::new("/proc/self/task").exists() {
        eprintln!("skipped: no /proc (not Linux)");
        return;
    }
    let cores = own_cores();
    if cores.len() < 2 {
        eprintln!("skipped: this process may use one core only ({cores:?}); nothing to keep off");
        return;
    }
    let frame = *cores.last().unwrap();
    let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));
    let mut child = vps
        .cmd()
        .args([
            "cluster",
            "--local-workers",
            "2",
            "--seconds",
            "3",
            "--json",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("vps starts");
    let pid = child.id();
    // Every mask seen while the session ran: coordinator threads by name, worker tasks by pid.
    let mut coordinator: BTreeMap<String, Vec<Vec<usize>>> = BTreeMap::new();
    let mut workers: BTreeMap<u32, Vec<(String, Vec<usize>)>> = BTreeMap::new();
    while child.try_wait().unwrap().is_none() {
        for (name, mask) in tasks(pid) {
            let seen = coordinator.entry(name).or_default();
            if !seen.contains(&mask) {
                seen.push(mask);
            }
        }
        for worker in children(pid).into_iter().filter(|&w| is_worker(w)) {
            let seen = workers.entry(worker).or_default();
            for task in tasks(worker) {
                if !seen.contains(&task) {
                    seen.push(task);
                }
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut out = String::new();
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    let report: serde_json::Value = serde_json::from_str(&out).expect("JSON report");
    assert_eq!(
        report["stats"]["frames"], 3000,
        "the session ran to its end"
    );

    let placement = &report["cluster"]["placement"];
    assert_eq!(placement["frame_core"], frame, "{placement}");
    let others: Vec<usize> = cores.iter().copied().filter(|&c| c != frame).collect();
    assert_eq!(placement["other_cores"], serde_json::json!(others));
    let pinned: Vec<&str> = placement["pinned"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l.as_str().unwrap())
        .collect();
    for role in [
        "coordinator network thread",
        "metrics thread",
        "local worker process",
    ] {
        assert!(
            pinned
                .iter()
                .any(|l| l.starts_with(role) && l.contains(&format!("cores {others:?}"))),
            "{role} not reported pinned: {pinned:?}"
        );
    }

    // The worker processes: two seen, and none of their threads may run on the frame core.
    let seen: Vec<_> = workers.iter().filter(|(_, t)| !t.is_empty()).collect();
    assert!(seen.len() >= 2, "worker processes seen: {workers:?}");
    for (worker, tasks) in seen {
        for (name, mask) in tasks {
            assert!(
                !mask.contains(&frame),
                "worker {worker} thread {name} may run on the frame core {frame}: {mask:?}"
            );
        }
    }
    // The coordinator's own threads: network and metrics off the frame core; the frame thread on
    // it (pinning is granted unprivileged). Each pins itself as its first act (the network
    // thread in the runtime's thread-start hook), so a sample may catch it named and not yet
    // pinned: the mask it keeps, the last seen, is the one checked.
    for name in ["vps-coord-net", "vps-metrics"] {
        let masks = coordinator
            .get(name)
            .unwrap_or_else(|| panic!("no {name} thread seen: {coordinator:?}"));
        let kept = masks.last().unwrap();
        assert!(
            !kept.contains(&frame),
            "{name} may run on {frame}: {masks:?}"
        );
    }
    assert_eq!(placement["frame_thread_pinned_core"], frame, "{placement}");
    let frame_masks = coordinator.get("vps-frame").expect("frame thread seen");
    assert!(
        frame_masks.contains(&vec![frame]),
        "frame thread masks {frame_masks:?}"
    );
}
