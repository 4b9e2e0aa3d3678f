//! Bicubic Bezier patch sets: a small text format and uniform tessellation into triangles.

use glam::DVec3;

use crate::validate::is_degenerate;
use crate::weld::weld_vertices;
use crate::TriMesh;

/// Control points and patches of a bicubic Bezier surface set (units of the source).
#[derive(Clone, Debug, PartialEq)]
pub struct BezierPatches {
    /// Control points.
    pub points: Vec<DVec3>,
    /// Each patch: 16 indices into `points`, row-major over the 4×4 net (u rows, v columns).
    pub patches: Vec<[u32; 16]>,
}

/// Parses the text format: `#` comments and blank lines ignored; a line `vertices N`, then N lines
/// `x y z`; a line `patches M`, then M lines of 16 zero-based vertex indices. Errors name the
/// 1-based line.
pub fn parse_bezier_patches(text: &str) -> Result<BezierPatches, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let mut next = |what: &str| {
        lines
            .next()
            .ok_or(format!("unexpected end of data, expected {what}"))
    };

    let count = |(line, text): (usize, &str), keyword: &str| -> Result<usize, String> {
        text.strip_prefix(keyword)
            .and_then(|rest| rest.trim().parse().ok())
            .ok_or(format!(
                "line {line}: expected '{keyword} <count>', found {text:?}"
            ))
    };
    let numbers = |(line, text): (usize, &str), n: usize| -> Result<Vec<f64>, String> {
        let values: Vec<f64> = text
            .split_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| format!("line {line}: {e}"))?;
        if values.len() != n {
            return Err(format!(
                "line {line}: expected {n} numbers, found {}",
                values.len()
            ));
        }
        Ok(values)
    };

    let n_points = count(next("'vertices N'")?, "vertices")?;
    let mut points = Vec::with_capacity(n_points.min(1 << 20));
    for _ in 0..n_points {
        let v = numbers(next("a vertex")?, 3)?;
        points.push(DVec3::new(v[0], v[1], v[2]));
    }
    let n_patches = count(next("'patches M'")?, "patches")?;
    let mut patches = Vec::with_capacity(n_patches.min(1 << 20));
    for _ in 0..n_patches {
        let line = next("a patch")?;
        let mut patch = [0u32; 16];
        for (slot, value) in patch.iter_mut().zip(numbers(line, 16)?) {
            if value.fract() != 0.0 || value < 0.0 || value >= n_points as f64 {
                return Err(format!(
                    "line {}: vertex index {value} is not in 0..{n_points}",
                    line.0
                ));
            }
            *slot = value as u32;
        }
        patches.push(patch);
    }
    Ok(BezierPatches { points, patches })
}

/// The cubic Bernstein basis at `t` in [0, 1].
fn bernstein(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t]
}

impl BezierPatches {
    /// Tessellates every patch on an `n × n` grid (`n` at least 1) into `2 n²` triangles, welds
    /// coincident vertices (patch seams), and drops triangles that are degenerate (collapsed rows).
    /// Triangle winding follows `∂P/∂u × ∂P/∂v`.
    pub fn tessellate(&self, n: u32) -> TriMesh {
        let n = n.max(1);
        let side = n + 1;
        let basis: Vec<[f64; 4]> = (0..side)
            .map(|i| bernstein(f64::from(i) / f64::from(n)))
            .collect();
        let mut mesh = TriMesh::default();
        for patch in &self.patches {
            let net = patch.map(|i| self.points[i as usize]);
            let base = mesh.vertices.len() as u32;
            for bu in &basis {
                for bv in &basis {
                    let mut p = DVec3::ZERO;
                    for r in 0..4 {
                        for c in 0..4 {
                            p += bu[r] * bv[c] * net[4 * r + c];
                        }
                    }
                    mesh.vertices.push(p);
                }
            }
            let at = |i: u32, j: u32| base + i * side + j;
            for i in 0..n {
                for j in 0..n {
                    mesh.triangles
                        .push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    mesh.triangles
                        .push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
        let mut mesh = weld_vertices(&mesh, 1e-9 * mesh.bounds().size().length());
        let vertices = &mesh.vertices;
        mesh.triangles
            .retain(|t| !is_degenerate(t, t.map(|i| vertices[i as usize])));
        mesh
    }
}
