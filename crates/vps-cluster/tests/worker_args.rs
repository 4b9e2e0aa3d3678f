//! The command line that `vps cluster --local-workers N` gives each `vps worker` process (the
//! processes themselves are tested with the real binary in the root package's
//! `tests/cluster_processes.rs`).

use vps_cluster::LocalWorkerArgs;

#[test]
fn local_worker_args_are_the_documented_command_line() {
    let args = LocalWorkerArgs {
        coordinator: "127.0.0.1:4433".parse().unwrap(),
        cert: "w.crt".into(),
        key: "w.key".into(),
        pins: vec!["c.crt".into(), "d.crt".into()],
        cache_dir: Some("cache".into()),
        threads: Some(2),
    };
    let got: Vec<String> = args
        .to_args()
        .iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        got.join(" "),
        "worker --coordinator 127.0.0.1:4433 --cert w.crt --key w.key --pin c.crt --pin d.crt \
         --cache cache --threads 2 --exit-with-coordinator"
    );
}
