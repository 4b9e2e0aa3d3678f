//! A read given up at its deadline stops its tessellating thread (alone in its own test binary:
//! it counts the process's threads by name, which other tests' reads would add to).

use std::path::PathBuf;
use std::time::{Duration, Instant};
use vps_step::{read_step, StepError, StepOptions};

/// Threads of this process named like the tessellating thread (Linux truncates names to 15
/// bytes: "vps-step tessel").
#[cfg(target_os = "linux")]
fn tessellating_threads() -> usize {
    std::fs::read_dir("/proc/self/task")
        .unwrap()
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
        .filter(|name| name.starts_with("vps-step tess"))
        .count()
}

#[cfg(target_os = "linux")]
#[test]
fn a_read_past_its_deadline_stops_its_thread() {
    // The filleted box at 1 µm with no triangle limit: minutes of tessellation (every face's grid
    // at its bound), given 50 ms.
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/step/fillet_box_ap214_is.step");
    let bytes = std::fs::read(path).unwrap();
    // A whole read first: the tessellator's worker pool (rayon's, started from the tessellating
    // thread, whose name its threads inherit) stays; only threads beyond it count.
    read_step(&bytes, &StepOptions::new(1e-3)).unwrap();
    let pool = tessellating_threads();
    let mut options = StepOptions::new(1e-6);
    options.max_triangles = usize::MAX / 4;
    options.deadline = Duration::from_millis(50);
    let e = read_step(&bytes, &options).unwrap_err();
    assert!(matches!(e, StepError::Deadline { .. }), "{e:?}");
    // Before, the thread ran on to its end (about 7 s here, where the bounds of `guard` stop this
    // tessellation); now it stops at its next evaluation. A liveness bound, not a timing: the
    // unit test `guard::tests::a_cancelled_budget_stops_at_the_next_evaluation` holds the
    // mechanism itself.
    let start = Instant::now();
    while tessellating_threads() > pool {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "the tessellating thread still runs {:?} after the deadline",
            start.elapsed()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}
