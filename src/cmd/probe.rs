//! `vps probe`: the voxel kind at world points read from a CSV file.

use crate::cli::ProbeArgs;
use anyhow::{bail, Context, Result};
use glam::DVec3;
use serde::Serialize;
use vps_app::output::{outln, print_json};

#[derive(Serialize)]
struct ProbeResult {
    line: usize,
    point_m: [f64; 3],
    voxel: [i32; 3],
    kind: &'static str,
}

/// The largest points file read, in bytes (1 GiB: about 30 million points).
const MAX_POINTS_FILE_BYTES: u64 = 1 << 30;

/// Parses the CSV text: one `x,y,z` (m) per line; blank lines and `#` comments skipped, and a
/// header (a first line of three fields none of which is a number, such as `x,y,z`). Errors name
/// the file and line.
fn parse_points(text: &str, file: &str) -> Result<Vec<(usize, DVec3)>> {
    let mut out = Vec::new();
    let mut first = true;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let is_header =
            first && fields.len() == 3 && fields.iter().all(|f| f.parse::<f64>().is_err());
        first = false;
        if is_header {
            continue;
        }
        if fields.len() != 3 {
            bail!(
                "{file}:{}: expected 3 comma-separated numbers x,y,z, found {}",
                i + 1,
                fields.len()
            );
        }
        let mut xyz = [0.0; 3];
        for (slot, field) in xyz.iter_mut().zip(&fields) {
            *slot = field
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .with_context(|| format!("{file}:{}: '{field}' is not a finite number", i + 1))?;
        }
        out.push((i + 1, DVec3::from_array(xyz)));
    }
    Ok(out)
}

/// Runs the command.
pub fn run(args: &ProbeArgs) -> Result<()> {
    let tree = vps_voxmap::file::load_voxmap(&args.voxmap)?;
    let name = args.points.display().to_string();
    let text = vps_files::read_regular_to_string(&args.points, MAX_POINTS_FILE_BYTES)
        .with_context(|| format!("reading {name}"))?;
    let results: Vec<ProbeResult> = parse_points(&text, &name)?
        .into_iter()
        .map(|(line, p)| {
            let ijk = tree.spec().index_of(p);
            ProbeResult {
                line,
                point_m: p.to_array(),
                voxel: ijk.to_array(),
                kind: tree.get(ijk).name(),
            }
        })
        .collect();
    if args.json {
        return print_json(&results);
    }
    for r in &results {
        outln!(
            "{:.6},{:.6},{:.6},{}",
            r.point_m[0],
            r.point_m[1],
            r.point_m[2],
            r.kind
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_points;
    use glam::DVec3;

    #[test]
    fn parses_and_reports_line_numbers() {
        let pts = parse_points("# header\n0,0,0\n\n1.5, 2, -3\n", "p.csv").unwrap();
        assert_eq!(pts.len(), 2);
        assert_eq!(pts[1].0, 4);
        let err = parse_points("0,0,0\n1,2\n", "p.csv")
            .unwrap_err()
            .to_string();
        assert!(err.contains("p.csv:2"), "{err}");
        let err = parse_points("0,nan,0\n", "p.csv").unwrap_err().to_string();
        assert!(err.contains("p.csv:1") && err.contains("nan"), "{err}");
    }

    /// A spreadsheet's header line (`x,y,z`) is skipped; the same words further down are an error.
    #[test]
    fn a_header_line_is_skipped_only_first() {
        let pts = parse_points("x, y, z\n0,0,0\n", "p.csv").unwrap();
        assert_eq!(pts, vec![(2, DVec3::ZERO)]);
        let err = parse_points("0,0,0\nx,y,z\n", "p.csv")
            .unwrap_err()
            .to_string();
        assert!(err.contains("p.csv:2") && err.contains("'x'"), "{err}");
        // A first line with a number in it is data, and its bad field is named.
        let err = parse_points("x,0,0\n", "p.csv").unwrap_err().to_string();
        assert!(err.contains("p.csv:1") && err.contains("'x'"), "{err}");
    }
}
