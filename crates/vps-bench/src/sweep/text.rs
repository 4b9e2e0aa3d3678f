//! `vps sweep`'s text for a person: the table (one line per row, `-` for a figure that was not
//! measured, with what each `-` means), and per scene the recommended voxel settings with the rule
//! that chose them. `--json` has every figure (a `-` is `null` there).

use crate::sweep::session::{SweepRow, SweepTable};
use vps_app::output::grouped;
use vps_session::file::{ForceModelName, ShellMethodName};

/// The frame compute p99.9 (µs) a recommended row must fit: 60 % of the 1 ms period, as
/// `vps tune`'s default budget.
pub const BUDGET_US: f64 = 600.0;

/// A figure to `decimals`, `-` when it was not measured (`null` in the JSON).
fn figure(value: Option<f64>, decimals: usize) -> String {
    value.map_or("-".into(), |v| format!("{v:.decimals$}"))
}

/// A voxel size in mm without float noise or trailing zeros (`2.5`, `10`).
fn size_mm(mm: f64) -> String {
    let text = format!("{mm:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Bytes as KiB or MiB.
fn memory(bytes: usize) -> String {
    if bytes < 1 << 20 {
        format!("{:.0} KiB", bytes as f64 / 1024.0)
    } else {
        format!("{:.1} MiB", bytes as f64 / 1048576.0)
    }
}

/// The scene file's name for a shell method.
fn method_name(m: ShellMethodName) -> &'static str {
    match m {
        ShellMethodName::Centres => "centres",
        ShellMethodName::Exact => "exact",
    }
}

/// A force model in the table's model column (8 characters at most).
fn model_name(m: ForceModelName) -> &'static str {
    match m {
        ForceModelName::TangentPlane => "tangent",
        ForceModelName::Distance => "distance",
    }
}

/// The table as text: a header, one line per row, the legend, then [`recommendations`].
pub fn table_text(table: &SweepTable) -> String {
    let mut out = String::new();
    if !table.complete {
        out += &format!("partial table: {}\n", vps_files::printable(&table.end));
    }
    out += &format!(
        "{:<14} {:<8} {:>7} {:>4} {:<7} {:>9} {:>9} {:>9} {:>9} {:>8} {:>13} {:>7} {:>8}\n",
        "scene",
        "model",
        "size mm",
        "bits",
        "method",
        "points",
        "voxmap",
        "p50 µs",
        "p99.9 µs",
        "PR",
        "dir° p50/p95",
        "|F| err",
        "min sep"
    );
    for r in &table.rows {
        let own = if r.default && r.default_size {
            "  * scene's own"
        } else {
            ""
        };
        out += &format!(
            "{:<14} {:<8} {:>7} {:>4} {:<7} {:>9} {:>9} {:>9.1} {:>9.1} {:>8} {:>13} {:>7} {:>8}{own}\n",
            vps_files::printable(&r.scene),
            model_name(r.force_model),
            size_mm(r.voxel_size_mm),
            r.voxel_width,
            method_name(r.method),
            grouped(r.shell_points as u64),
            memory(r.voxmap_bytes),
            r.compute_p50_us,
            r.compute_p999_us,
            figure(r.penetration_ratio, 4),
            format!(
                "{}/{}",
                figure(r.direction_error_deg_p50, 1),
                figure(r.direction_error_deg_p95, 1)
            ),
            figure(r.magnitude_error_p50, 2),
            figure(r.min_separation_mm, 2),
        );
    }
    out += LEGEND;
    for line in recommendations(&table.rows) {
        out += &line;
        out.push('\n');
    }
    out
}

/// What each column and each `-` means.
const LEGEND: &str = "\
columns: model: force model (tangent: the paper's tangent-plane model on voxel layers;
  distance: the signed-distance band with a stand-off); points: shell points; voxmap: tree memory; p50/p99.9 µs: frame compute, free-running,
  one thread, on this machine now; PR: penetration ratio, frames with a shell point inside an
  obstacle over frames touching one (0 is best); dir° p50/p95: angle between the voxel force and
  the exact mesh reference's force, median and 95th percentile over the compared frames; |F| err:
  median of |voxel force / exact force - 1|; min sep: the smallest exact distance of any shell
  point from an obstacle over the compared frames (mm, negative: inside it);
  *: the scene file's own model, width, method and size.
-: not measured (null in --json): PR when the session never touched an obstacle; dir°, |F| err
  when no compared frame had both a voxel and an exact force; min sep when no frame was compared.
";

/// Per scene, the recommended setting: of the rows with accuracy figures, those with the lowest
/// penetration ratio, of those the ones whose p99.9 fits [`BUDGET_US`] (all of them when none
/// does, said so), of those the lowest force direction error p50 to the whole degree, then the
/// smallest non-negative minimum exact separation (the closest the part came to the scene
/// without entering it: the tightest clearance the setting resolves; the distance model's
/// direction error is near 0° at every size, so this is what tells its sizes apart), then fewer
/// shell points, then the smaller voxmap (the distance model's forces do not depend on the voxel
/// width, so of its widths the narrowest). A scene none of whose rows touched an obstacle gets no recommendation, and says
/// why.
pub fn recommendations(rows: &[SweepRow]) -> Vec<String> {
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let mut lines = Vec::new();
    for scene in scenes {
        let name = vps_files::printable(scene);
        let measured: Vec<&SweepRow> = rows
            .iter()
            .filter(|r| r.scene == scene)
            .filter(|r| r.penetration_ratio.is_some() && r.direction_error_deg_p50.is_some())
            .collect();
        let Some(best_pr) = measured
            .iter()
            .filter_map(|r| r.penetration_ratio)
            .min_by(f64::total_cmp)
        else {
            lines.push(format!(
                "{name}: no recommendation: no row's session pressed the part on an obstacle, so \
                 there is no accuracy to compare (give the scene a hand path that touches a \
                 surface early, docs/scenes.md)"
            ));
            continue;
        };
        let lowest: Vec<&SweepRow> = measured
            .into_iter()
            .filter(|r| r.penetration_ratio == Some(best_pr))
            .collect();
        let fitting: Vec<&SweepRow> = lowest
            .iter()
            .copied()
            .filter(|r| r.compute_p999_us <= BUDGET_US)
            .collect();
        let over_budget = fitting.is_empty();
        let pool = if over_budget { lowest } else { fitting };
        let degrees = |r: &SweepRow| r.direction_error_deg_p50.map_or(f64::INFINITY, f64::round);
        let separation = |r: &SweepRow| {
            r.min_separation_mm
                .filter(|&mm| mm >= 0.0)
                .unwrap_or(f64::INFINITY)
        };
        let best = pool
            .into_iter()
            .min_by(|a, b| {
                degrees(a)
                    .total_cmp(&degrees(b))
                    .then(separation(a).total_cmp(&separation(b)))
                    .then(a.shell_points.cmp(&b.shell_points))
                    .then(a.voxmap_bytes.cmp(&b.voxmap_bytes))
            })
            .expect("a scene with measured rows has a best one");
        let own = if best.default && best.default_size {
            " (the scene file's own setting)"
        } else {
            ""
        };
        lines.push(format!(
            "recommended for {name}: [voxels] force_model = \"{}\", voxel_size = \"{}mm\", \
             voxel_width = {}, shell_method = \"{}\"{own}: penetration ratio {}, force direction error p50 {:.1}° \
             (p95 {}°), min exact separation {} mm, frame compute p99.9 {:.1} µs{}",
            best.force_model.name(),
            size_mm(best.voxel_size_mm),
            best.voxel_width,
            method_name(best.method),
            figure(best.penetration_ratio, 4),
            best.direction_error_deg_p50.unwrap_or(f64::NAN),
            figure(best.direction_error_deg_p95, 1),
            figure(best.min_separation_mm, 2),
            best.compute_p999_us,
            if over_budget {
                format!(" (no row with that penetration ratio fits {BUDGET_US:.0} µs here)")
            } else {
                format!(" (within {BUDGET_US:.0} µs)")
            }
        ));
    }
    if !lines.is_empty() {
        lines.push(format!(
            "  rule: the lowest penetration ratio, then frame compute p99.9 within {BUDGET_US:.0} \
             µs (60 % of the 1 ms period), then the lowest force direction error p50 to the \
             whole degree, then the smallest non-negative min exact separation (the tightest \
             clearance resolved), then fewer shell points, then the smaller voxmap{}",
            if cfg!(debug_assertions) {
                "; this vps was built without --release, so its timings are no guide to a \
                 release build's"
            } else {
                ""
            }
        ));
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(size: f64, pr: Option<f64>, dir: Option<f64>, p999: f64) -> SweepRow {
        SweepRow {
            scene: "s".into(),
            method: ShellMethodName::Exact,
            voxel_size_mm: size,
            voxel_width: 4,
            force_model: ForceModelName::TangentPlane,
            default: true,
            default_size: size == 5.0,
            voxelized: "scene".into(),
            shell_points: (1000.0 / size) as usize,
            voxmap_bytes: 4096,
            voxelize_ms: 1.0,
            frames: 100,
            compute_p50_us: p999 / 2.0,
            compute_p999_us: p999,
            penetration_ratio: pr,
            compared_frames: 10,
            both_force_frames: 10,
            voxel_only_frames: 0,
            reference_only_frames: 0,
            direction_error_deg_p50: dir,
            direction_error_deg_p95: dir.map(|d| 2.0 * d),
            magnitude_error_p50: Some(0.1),
            magnitude_ratio_p50: Some(0.9),
            min_separation_mm: Some(1.0),
        }
    }

    /// The lowest penetration ratio wins over a lower direction error; of equal ratios the
    /// lowest direction error within the budget; a row over budget is passed over.
    #[test]
    fn the_recommendation_follows_its_rule() {
        let rows = [
            row(10.0, Some(0.01), Some(1.0), 10.0),
            row(5.0, Some(0.0), Some(4.0), 20.0),
            row(2.5, Some(0.0), Some(3.0), 100.0),
            row(1.25, Some(0.0), Some(2.0), 5000.0),
        ];
        let lines = recommendations(&rows);
        assert!(
            lines[0].starts_with("recommended for s: [voxels] force_model = \"tangent-plane\", voxel_size = \"2.5mm\", voxel_width = 4, shell_method = \"exact\": penetration ratio 0.0000, force direction error p50 3.0°"),
            "{lines:?}"
        );
        assert!(
            lines[1].contains("rule: the lowest penetration ratio"),
            "{lines:?}"
        );
    }

    /// Direction errors within the same whole degree tie; the row whose part came closest to the
    /// scene without entering it wins (a negative separation, inside it, never does).
    #[test]
    fn a_tie_in_direction_goes_to_the_tightest_clearance_resolved() {
        let with = |size, dir, sep: f64| SweepRow {
            min_separation_mm: Some(sep),
            ..row(size, Some(0.0), Some(dir), 50.0)
        };
        let rows = [
            with(10.0, 0.0, 4.3),
            with(2.5, 0.3, 0.6),
            with(1.25, 0.2, -0.1),
            with(5.0, 1.6, 0.1),
        ];
        let lines = recommendations(&rows);
        assert!(
            lines[0].contains("voxel_size = \"2.5mm\"") && lines[0].contains("separation 0.60 mm"),
            "{lines:?}"
        );
    }

    /// Rows equal in every figure but the voxmap's memory (the distance model at each width) go
    /// to the smaller voxmap, whatever their order.
    #[test]
    fn a_tie_in_every_figure_goes_to_the_smaller_voxmap() {
        let at = |bits: u32, bytes: usize| SweepRow {
            voxel_width: bits,
            voxmap_bytes: bytes,
            ..row(5.0, Some(0.0), Some(1.0), 50.0)
        };
        for rows in [
            [at(4, 3 << 20), at(2, 1 << 20), at(8, 9 << 20)],
            [at(8, 9 << 20), at(4, 3 << 20), at(2, 1 << 20)],
        ] {
            let lines = recommendations(&rows);
            assert!(lines[0].contains("voxel_width = 2,"), "{lines:?}");
        }
    }

    /// A sweep without contact has `-` for its accuracy, explained, and no recommendation.
    #[test]
    fn unmeasured_figures_are_dashes_with_a_reason() {
        let table = SweepTable {
            complete: true,
            end: "all rows done".into(),
            rows: vec![row(10.0, None, None, 10.0)],
        };
        let text = table_text(&table);
        let row = text.lines().nth(1).unwrap();
        assert!(row.starts_with("s ") && row.contains(" -/- "), "{text}");
        assert!(!row.contains("null") && !text.contains("NaN"), "{text}");
        assert!(text.contains("-: not measured (null in --json)"), "{text}");
        assert!(
            text.contains("s: no recommendation: no row's session pressed"),
            "{text}"
        );
    }
}
