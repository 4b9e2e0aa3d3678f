//! `vps bench scaling`: how many shell points fit the frame budget as compute is added, over 1..N
//! local compute threads (`vps bench loop --threads k`) and 1..N local worker processes
//! (`vps bench cluster --workers w`, each worker one thread, the coordinator one thread for its own
//! share), N being the machine's cores by default.
//!
//! Each configuration runs as a child `vps` process (the same binary) at two or more shell sizes;
//! a straight line through compute p99.9 against points gives the points per frame whose p99.9
//! meets the budget: `(budget − intercept) / slope`. The slope is the least-squares slope of p99.9,
//! but at least that of p50: a tail sample is one frame in a thousand, so on a loaded machine one
//! preemption can flatten the p99.9 line, and the marginal cost of a point at the tail is not below
//! its typical cost. The intercept then puts the line through the mean of the p99.9 samples. Parallel efficiency is that figure
//! over `units × ` the one-thread figure, with `units` the compute threads (threads: k; processes:
//! w workers + the coordinator's thread). One JSON report and, with `--plot`, one SVG of both.

use crate::machine::load_average;
use crate::svg::{draw_legend, write_svg};
use anyhow::{bail, Context, Result};
use plotters::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::process::Command;
use vps_app::output::print_report;

/// What to measure.
#[derive(Clone, Debug)]
pub struct ScalingBench {
    /// Largest thread and worker count (≥ 1).
    pub max_units: usize,
    /// Shell sizes to run each configuration at (at least two distinct).
    pub points: Vec<usize>,
    /// Frames per run (1 ms each).
    pub frames: u64,
    /// Compute budget per frame (µs) that p99.9 must meet.
    pub budget_us: f64,
}

/// One run of one configuration.
#[derive(Serialize)]
struct Run {
    /// Shell points of the run (the requested size, as resampled).
    points: usize,
    compute_p50_us: f64,
    compute_p999_us: f64,
    missed_deadlines: u64,
    frames: u64,
}

/// One configuration: `units` compute threads or worker processes.
#[derive(Serialize)]
struct Configuration {
    /// Threads (`threads`) or worker processes (`processes`).
    threads_or_workers: usize,
    /// Compute threads in use: k, or w workers + the coordinator's thread.
    compute_units: usize,
    runs: Vec<Run>,
    /// Points per frame whose compute p99.9 meets the budget (linear fit); null when the fit has
    /// no positive slope (too noisy to say).
    points_at_budget: Option<f64>,
    /// `points_at_budget / (compute_units · one-thread points_at_budget)`.
    parallel_efficiency: Option<f64>,
}

#[derive(Serialize)]
struct HostLoad {
    cpus: usize,
    load_before: Option<f64>,
    load_after: Option<f64>,
}

#[derive(Serialize)]
struct ScalingReport {
    command: String,
    method: &'static str,
    budget_us: f64,
    frames_per_run: u64,
    host: HostLoad,
    threads: Vec<Configuration>,
    processes: Vec<Configuration>,
}

/// Runs the benchmark, prints JSON and writes the plot to `plot` if given.
pub fn run(bench: &ScalingBench, plot: Option<&Path>, json: bool) -> Result<()> {
    let mut sizes = bench.points.clone();
    sizes.sort_unstable();
    sizes.dedup();
    if sizes.len() < 2 || bench.max_units == 0 {
        bail!("--points needs at least two distinct sizes and --max at least 1");
    }
    let load_before = load_average();
    let exe = std::env::current_exe().context("locating the vps binary")?;
    let frames = bench.frames.to_string();
    // `vps bench BENCH --points P TAIL...` at every size.
    let at_every_size = |bench: &str, tail: &[&str]| -> Result<Vec<Run>> {
        sizes
            .iter()
            .map(|p| child_run(&exe, &["bench", bench, "--points", &p.to_string()], tail))
            .collect()
    };
    let mut threads = Vec::new();
    for k in 1..=bench.max_units {
        let k_text = k.to_string();
        let runs = at_every_size("loop", &["--frames", &frames, "--threads", &k_text])?;
        threads.push(configuration(k, k, runs, bench.budget_us));
    }
    let mut processes = Vec::new();
    for w in 1..=bench.max_units {
        let w_text = w.to_string();
        let tail = [
            "--frames",
            &frames,
            "--workers",
            &w_text,
            "--worker-threads",
            "1",
            "--threads",
            "1",
        ];
        let runs = at_every_size("cluster", &tail)?;
        processes.push(configuration(w, w + 1, runs, bench.budget_us));
    }
    let one = threads.first().and_then(|c| c.points_at_budget);
    for c in threads.iter_mut().chain(processes.iter_mut()) {
        c.parallel_efficiency = match (c.points_at_budget, one) {
            (Some(p), Some(one)) if one > 0.0 => Some(p / (c.compute_units as f64 * one)),
            _ => None,
        };
    }
    let report = ScalingReport {
        command: format!(
            "vps bench scaling --max {} --points {} --frames {} --budget-us {}",
            bench.max_units,
            sizes
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(","),
            bench.frames,
            bench.budget_us
        ),
        method: "each configuration a child `vps bench loop` (threads) or `vps bench cluster` \
                 (worker processes, one thread each, plus the coordinator's thread) per shell size; \
                 points at budget from a least-squares line through compute p99.9 against points",
        budget_us: bench.budget_us,
        frames_per_run: bench.frames,
        host: HostLoad {
            cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
            load_before,
            load_after: load_average(),
        },
        threads,
        processes,
    };
    if let Some(path) = plot {
        plot_scaling(&report, path).with_context(|| format!("plotting {}", path.display()))?;
    }
    print_report(
        "bench scaling: points per frame within the budget against threads and worker processes",
        &report,
        json,
    )
}

/// Runs `vps <head> <tail>` and reads its JSON report's shell size and compute percentiles.
fn child_run(exe: &Path, head: &[&str], tail: &[&str]) -> Result<Run> {
    let shown = format!("vps {} {}", head.join(" "), tail.join(" "));
    let out = Command::new(exe)
        .args(head)
        .args(tail)
        .arg("--json")
        .output()
        .with_context(|| format!("running {shown}"))?;
    if !out.status.success() {
        bail!(
            "{shown} failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let json: serde_json::Value = serde_json::from_slice(&out.stdout)
        .with_context(|| format!("reading the JSON of {shown}"))?;
    let field = |path: &[&str]| -> Result<u64> {
        path.iter()
            .try_fold(&json, |v, k| v.get(k))
            .and_then(serde_json::Value::as_u64)
            .with_context(|| format!("{shown}: no `{}` in its report", path.join(".")))
    };
    Ok(Run {
        points: field(&["shell_points"])? as usize,
        compute_p50_us: field(&["stats", "compute_ns", "p50"])? as f64 / 1e3,
        compute_p999_us: field(&["stats", "compute_ns", "p999"])? as f64 / 1e3,
        missed_deadlines: field(&["stats", "missed_deadlines"])?,
        frames: field(&["stats", "frames"])?,
    })
}

fn configuration(count: usize, units: usize, runs: Vec<Run>, budget_us: f64) -> Configuration {
    let tail: Vec<(f64, f64)> = runs
        .iter()
        .map(|r| (r.points as f64, r.compute_p999_us))
        .collect();
    let median: Vec<(f64, f64)> = runs
        .iter()
        .map(|r| (r.points as f64, r.compute_p50_us))
        .collect();
    Configuration {
        threads_or_workers: count,
        compute_units: units,
        runs,
        points_at_budget: points_at_budget(&tail, &median, budget_us),
        parallel_efficiency: None,
    }
}

/// Mean `x`, mean `y` and least-squares slope of `(x, y)` samples.
fn fit(samples: &[(f64, f64)]) -> (f64, f64, f64) {
    let n = samples.len() as f64;
    let (sx, sy) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) = samples.iter().fold((0.0, 0.0), |(a, b), &(x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    (mx, my, sxy / sxx)
}

/// The points whose tail time reaches `budget` (see the module docs): a line through the `tail`
/// samples' mean with the larger of the `tail` and `median` least-squares slopes. None without a
/// positive slope; never negative (a budget below the intercept fits no points).
fn points_at_budget(tail: &[(f64, f64)], median: &[(f64, f64)], budget: f64) -> Option<f64> {
    let (mx, my, tail_slope) = fit(tail);
    let slope = tail_slope.max(fit(median).2);
    if slope.is_nan() || slope <= 0.0 {
        return None;
    }
    let intercept = my - slope * mx;
    Some(((budget - intercept) / slope).max(0.0))
}

/// A plotted line: legend, colour, points.
type Line = (&'static str, RGBColor, Vec<(f64, f64)>);

/// Left: points at budget against compute units; right: parallel efficiency. One line for threads,
/// one for worker processes.
fn plot_scaling(report: &ScalingReport, path: &Path) -> Result<()> {
    write_svg(path, (960, 420), |root| {
        let panels = root.split_evenly((1, 2));
        type Value = fn(&Configuration) -> Option<f64>;
        let figures: [(&str, Value); 2] = [
            ("points per frame at the budget (p99.9)", |c| {
                c.points_at_budget
            }),
            ("parallel efficiency", |c| c.parallel_efficiency),
        ];
        let max_units = report
            .threads
            .iter()
            .chain(&report.processes)
            .map(|c| c.compute_units)
            .max()
            .unwrap_or(1) as f64;
        for (panel, (label, value)) in panels.iter().zip(figures) {
            let lines: [Line; 2] = [
                ("local threads", BLUE, series(&report.threads, value)),
                ("worker processes", RED, series(&report.processes, value)),
            ];
            let y1 = lines
                .iter()
                .flat_map(|l| l.2.iter().map(|p| p.1))
                .fold(0.0f64, f64::max)
                .max(1e-9)
                * 1.15;
            let mut chart = ChartBuilder::on(panel)
                .caption(label, ("sans-serif", 16))
                .margin(12)
                .x_label_area_size(36)
                .y_label_area_size(70)
                .build_cartesian_2d(0.5..(max_units + 0.5), 0.0..y1)?;
            chart
                .configure_mesh()
                .x_desc("compute threads (processes: workers + coordinator)")
                .y_desc(label)
                .draw()?;
            for (name, colour, pts) in lines {
                let style = ShapeStyle::from(colour).stroke_width(2);
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), style))?
                    .label(name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style));
                chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
            }
            draw_legend(&mut chart)?;
        }
        Ok(())
    })
}

fn series(configs: &[Configuration], value: fn(&Configuration) -> Option<f64>) -> Vec<(f64, f64)> {
    configs
        .iter()
        .filter_map(|c| value(c).map(|v| (c.compute_units as f64, v)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_point_of_a_line_and_of_noise() {
        // y = 50 + 0.01 x: 1000 µs at x = 95,000.
        let line = [(20_000.0, 250.0), (100_000.0, 1050.0)];
        let flat = [(20_000.0, 100.0), (100_000.0, 100.0)];
        let x = points_at_budget(&line, &flat, 1000.0).expect("positive slope");
        assert!((x - 95_000.0).abs() < 1e-6, "{x}");
        // Below the intercept nothing fits; falling lines say nothing.
        assert_eq!(points_at_budget(&line, &flat, 10.0), Some(0.0));
        let falling = [(1.0, 5.0), (2.0, 4.0)];
        assert_eq!(points_at_budget(&falling, &falling, 10.0), None);
        // A tail flattened by one preempted frame takes the median's slope (0.004 µs per point),
        // through the tail's mean (600 µs at 60,000 points): 1000 µs at 160,000 points.
        let preempted = [(20_000.0, 590.0), (100_000.0, 610.0)];
        let median = [(20_000.0, 80.0), (100_000.0, 400.0)];
        let x = points_at_budget(&preempted, &median, 1000.0).expect("median slope");
        assert!((x - 160_000.0).abs() < 1e-6, "{x}");
    }
}
