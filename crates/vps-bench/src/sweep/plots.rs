//! SVG plots of `vps sweep`: one figure per column against voxel size (log2 axis), one line per
//! scene, shell method and voxel width: the colour names the scene and method, the line the width
//! (solid 2-bit, dashed 4-bit, dotted 8-bit) and the marker too (circle, triangle, cross); the
//! scene's own width and method (`default` rows) are drawn thicker.

use crate::svg::{draw_legend, write_svg};
use crate::sweep::session::SweepRow;
use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::Path;

/// A figure: file stem, y-axis label, the value of a row.
type Figure = (&'static str, &'static str, fn(&SweepRow) -> Option<f64>);

const FIGURES: &[Figure] = &[
    ("shell-points", "shell points", |r| {
        Some(r.shell_points as f64)
    }),
    ("voxmap-mib", "voxmap memory (MiB)", |r| {
        Some(r.voxmap_bytes as f64 / 1048576.0)
    }),
    ("voxelize-ms", "voxelization + tree (ms)", |r| {
        Some(r.voxelize_ms)
    }),
    ("compute-p50-us", "frame compute p50 (µs)", |r| {
        Some(r.compute_p50_us)
    }),
    ("compute-p999-us", "frame compute p99.9 (µs)", |r| {
        Some(r.compute_p999_us)
    }),
    ("penetration-ratio", "penetration ratio", |r| {
        r.penetration_ratio
    }),
    (
        "direction-error-deg",
        "force direction error p50 (deg)",
        |r| r.direction_error_deg_p50,
    ),
    (
        "magnitude-error",
        "force magnitude error p50 (relative)",
        |r| r.magnitude_error_p50,
    ),
    ("min-separation-mm", "minimum exact separation (mm)", |r| {
        r.min_separation_mm
    }),
];

const COLOURS: [RGBColor; 6] = [BLUE, RED, GREEN, MAGENTA, CYAN, BLACK];

/// One line of a figure: its legend, colour, width (bits) and rows.
struct Series<'a> {
    label: String,
    colour: RGBColor,
    width_bits: u32,
    /// The scene's own width and method (drawn thicker, "(default)" in the legend).
    default: bool,
    rows: Vec<&'a SweepRow>,
}

/// Groups rows into series by scene, method and width, in order of first appearance; one colour
/// per scene and method.
fn series_of(rows: &[SweepRow]) -> Vec<Series<'_>> {
    let mut groups: Vec<String> = Vec::new();
    let mut series: Vec<Series> = Vec::new();
    for r in rows {
        let group = format!("{} / {:?}", r.scene, r.method).to_lowercase();
        let label = format!(
            "{group} / {}-bit{}",
            r.voxel_width,
            if r.default { " (default)" } else { "" }
        );
        if let Some(s) = series.iter_mut().find(|s| s.label == label) {
            s.rows.push(r);
            continue;
        }
        let g = match groups.iter().position(|g| *g == group) {
            Some(g) => g,
            None => {
                groups.push(group);
                groups.len() - 1
            }
        };
        series.push(Series {
            label,
            colour: COLOURS[g % COLOURS.len()],
            width_bits: r.voxel_width,
            default: r.default,
            rows: vec![r],
        });
    }
    series
}

/// Writes `DIR/<figure>.svg` for every figure.
pub fn plot_all(rows: &[SweepRow], dir: &Path) -> Result<()> {
    let series = series_of(rows);
    for (stem, label, value) in FIGURES {
        let path = dir.join(format!("{stem}.svg"));
        plot_one(&series, label, *value, &path)
            .with_context(|| format!("plotting {}", path.display()))?;
    }
    Ok(())
}

fn plot_one(
    series: &[Series],
    label: &str,
    value: fn(&SweepRow) -> Option<f64>,
    path: &Path,
) -> Result<()> {
    let points: Vec<(usize, Vec<(f64, f64)>)> = series
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let pts = s
                .rows
                .iter()
                .filter_map(|r| value(r).map(|v| (r.voxel_size_mm.log2(), v)))
                .collect();
            (i, pts)
        })
        .collect();
    let all = points.iter().flat_map(|(_, p)| p.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let pad = ((y1 - y0).abs() * 0.1).max(1e-9);
    let y0 = if y0 >= 0.0 {
        (y0 - pad).max(0.0)
    } else {
        y0 - pad
    };
    write_svg(path, (720, 440), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(format!("{label} against voxel size"), ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0 - 0.3)..(x1 + 0.3), y0..(y1 + pad))?;
        chart
            .configure_mesh()
            .x_desc("voxel size (mm, log scale)")
            .y_desc(label)
            .x_label_formatter(&|v| format!("{}", (2f64.powf(*v) * 1000.0).round() / 1000.0))
            .draw()?;
        for (i, pts) in &points {
            let s = &series[*i];
            let (colour, bits) = (s.colour, s.width_bits);
            let style = ShapeStyle::from(colour).stroke_width(if s.default { 3 } else { 1 });
            let line = pts.iter().copied();
            let drawn = match bits {
                2 => chart.draw_series(LineSeries::new(line, style))?,
                4 => chart.draw_series(DashedLineSeries::new(line, 8, 5, style))?,
                _ => chart.draw_series(DashedLineSeries::new(line, 2, 4, style))?,
            };
            drawn
                .label(s.label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style));
            let fill = colour.filled();
            match bits {
                2 => {
                    chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, fill)))?;
                }
                4 => {
                    chart.draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 4, fill)))?;
                }
                _ => {
                    chart.draw_series(
                        pts.iter().map(|&p| Cross::new(p, 4, style.stroke_width(2))),
                    )?;
                }
            }
        }
        draw_legend(&mut chart)?;
        Ok(())
    })
}
