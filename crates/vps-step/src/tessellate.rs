//! One closed shell of a B-rep to triangles, by the truck kernel, checked.
//!
//! truck converts the shell's faces, edges and surfaces and triangulates them within a chord
//! tolerance. It sometimes returns a surface with holes or no triangles at all for a face it
//! cannot lay out (cones and tori in truck-meshalgo 0.4 do this), and it may panic on malformed
//! geometry, so every result is checked here: the triangles must form a closed, consistently
//! oriented surface (every directed edge once, its reverse once) enclosing a positive volume, or
//! the solid is refused with the reason.

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use truck_meshalgo::prelude::*;
use truck_stepio::r#in::alias::{Curve3D, Surface};
use truck_stepio::r#in::Table;
use truck_topology::compress::{
    CompressedEdge, CompressedEdgeIndex, CompressedFace, CompressedShell,
};

use crate::guard::{
    unwind_if_cancelled, Cancelled, DivisionBudget, Guarded, GuardedCurve, OutOfEvaluations,
    FIRST_PASS_POINTS,
};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// A shell as triangles, in file units.
#[derive(Clone, Debug, Default)]
pub struct ShellMesh {
    /// Vertex positions (file units), each distinct position once.
    pub vertices: Vec<DVec3>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl ShellMesh {
    /// The enclosed volume (file units cubed; negative when the triangles face inwards).
    pub fn volume(&self) -> f64 {
        enclosed_volume(&self.vertices, &self.triangles)
    }

    /// The same surface facing the other way.
    pub fn flipped(mut self) -> Self {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
        self
    }

    /// Edges used other than once in each direction (0 for a closed, consistently oriented
    /// surface).
    pub fn open_edges(&self) -> usize {
        open_edge_count(&self.triangles)
    }
}

/// The volume `triangles` over `vertices` enclose (the vertices' unit cubed; negative when the
/// triangles face inwards): the divergence theorem's sum of signed tetrahedra.
pub fn enclosed_volume(vertices: &[DVec3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Directed edges of `triangles` used other than once, or whose reverse is not used exactly once
/// (0 for a closed, consistently oriented surface).
pub fn open_edge_count(triangles: &[[u32; 3]]) -> usize {
    let mut directed: HashMap<(u32, u32), i32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *directed.entry((a, b)).or_default() += 1;
        }
    }
    directed
        .iter()
        .filter(|(&(a, b), &n)| n != 1 || directed.get(&(b, a)) != Some(&1))
        .count()
}

/// Why a shell could not be triangulated.
#[derive(Debug)]
pub enum ShellFailure {
    /// The shell is not one truck read.
    NotRead,
    /// truck could not build its faces and edges.
    Convert(String),
    /// truck panicked.
    Panicked(String),
    /// The triangles leave `open_edges` edges open.
    Open {
        /// Edges not matched once each way.
        open_edges: usize,
        /// Triangles produced.
        triangles: usize,
        /// Faces of the shell.
        faces: usize,
        /// The surface kind of each face the tessellator returned nothing for (`ConicalSurface`,
        /// `SphericalSurface`, ...).
        failed_faces: Vec<String>,
    },
    /// The triangles enclose no positive volume.
    NoVolume,
    /// A face or edge could not be laid out within the bounds of [`crate::guard`] (its grid, its
    /// evaluations, its polyline): not smooth at the tolerance, or malformed geometry.
    Diverged {
        /// What ran over: `a face on its NurbsSurface`, `an edge on its BSplineCurve`.
        surface: String,
    },
    /// The read's deadline passed and stopped it.
    Cancelled,
    /// More triangles than allowed.
    TooMany {
        /// The estimate or count.
        triangles: usize,
    },
}

impl std::fmt::Display for ShellFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotRead => write!(f, "its shell is not one the geometry kernel could read"),
            Self::Convert(e) => write!(f, "the geometry kernel could not read its faces: {e}"),
            Self::Panicked(e) => write!(f, "the geometry kernel failed on it ({e})"),
            Self::Open {
                open_edges,
                triangles,
                faces,
                failed_faces,
            } => {
                write!(
                    f,
                    "its {triangles} triangles do not close ({open_edges} open edges)"
                )?;
                if failed_faces.is_empty() {
                    write!(f, ": the tessellator left gaps between its {faces} faces")
                } else {
                    let mut kinds: Vec<(String, usize)> = Vec::new();
                    for k in failed_faces {
                        match kinds.iter_mut().find(|(n, _)| n == k) {
                            Some((_, c)) => *c += 1,
                            None => kinds.push((k.clone(), 1)),
                        }
                    }
                    let listed: Vec<String> =
                        kinds.iter().map(|(k, c)| format!("{c} {k}")).collect();
                    write!(
                        f,
                        ": the tessellator (truck-meshalgo 0.4) could not mesh {} of its {faces} \
                         faces ({})",
                        failed_faces.len(),
                        listed.join(", ")
                    )
                }
            }
            Self::NoVolume => write!(f, "its triangles enclose no volume"),
            Self::Diverged { surface } => write!(
                f,
                "the geometry kernel could not lay out {surface} within the bounds vps sets on \
                 tessellation (a face's grid: {} passes and at most half the triangle limit in \
                 points; its surface evaluations; an edge's polyline: {} points): the geometry is \
                 not smooth at the chord tolerance or is malformed",
                crate::guard::MAX_PASSES,
                crate::guard::EDGE_POINTS
            ),
            Self::TooMany { triangles } => write!(f, "it needs about {triangles} triangles"),
            Self::Cancelled => write!(f, "its tessellation was stopped at the read's deadline"),
        }
    }
}

/// Triangulates closed shell `shell` of `table` within `tolerance` (file units), facing outwards
/// (positive volume) whatever the file's orientation, refusing it when
/// about more than `max_triangles` would be needed (estimated from a coarse pass first, so a
/// too-fine tolerance fails fast instead of exhausting memory).
///
/// `coarse_limit` (file units) caps the coarse pass's tolerance: truck refuses a tolerance above a
/// sphere's radius, so the caller passes half the smallest sphere radius of the file.
pub fn shell(
    table: &Table,
    shell: u64,
    tolerance: f64,
    coarse_limit: f64,
    max_triangles: usize,
    cancelled: &Arc<AtomicBool>,
) -> Result<ShellMesh, ShellFailure> {
    let holder = table.shell.get(&shell).ok_or(ShellFailure::NotRead)?;
    let budget_slot = std::sync::OnceLock::<std::sync::Arc<DivisionBudget>>::new();
    let run = || -> Result<(ShellMesh, usize, Vec<String>), ShellFailure> {
        // Each face's surface divided and evaluated under one budget ([`crate::guard`]): in the
        // first pass at most `FIRST_PASS_POINTS` grid points a face, in the fine pass after it
        // half the triangle limit (two triangles a cell); a face over its budget unwinds out of
        // truck with `OutOfEvaluations`, caught below.
        let shell_read = table
            .to_compressed_shell(holder)
            .map_err(|e| ShellFailure::Convert(e.to_string()))?;
        let budget = DivisionBudget::new(
            shell_read.faces.len(),
            FIRST_PASS_POINTS.min(max_triangles / 2),
            cancelled.clone(),
        );
        let _ = budget_slot.set(budget.clone());
        let compressed = guarded(shell_read, &budget);
        // A coarse pass (1 % of the shell's size) sizes the fine one: triangles grow about as
        // 1 / tolerance.
        let corners: Vec<DVec3> = compressed
            .vertices
            .iter()
            .map(|p| DVec3::new(p.x, p.y, p.z))
            .collect();
        let size = bounds_diagonal(&corners);
        let weld = tolerance * 1e-3;
        let coarse_tolerance = (size * 0.01).min(coarse_limit).max(tolerance);
        // A shell small against its tolerance has no coarser pass: the fine one is the only one
        // (its count is checked below).
        if coarse_tolerance > tolerance {
            let coarse = to_mesh(
                &compressed
                    .robust_triangulation(coarse_tolerance)
                    .to_polygon(),
                weld,
            );
            budget.start_pass(max_triangles / 2);
            let estimate = (coarse.triangles.len() as f64 * coarse_tolerance / tolerance).ceil();
            if estimate > max_triangles as f64 {
                return Err(ShellFailure::TooMany {
                    triangles: estimate as usize,
                });
            }
        }
        let triangulated = compressed.robust_triangulation(tolerance);
        let surfaces: Vec<&Guarded> = compressed.faces.iter().map(|f| &f.surface).collect();
        let (mesh, failed_faces) =
            assemble(&triangulated, &surfaces, weld, max_triangles, cancelled);
        if mesh.triangles.len() > max_triangles {
            return Err(ShellFailure::TooMany {
                triangles: mesh.triangles.len(),
            });
        }
        Ok((mesh, compressed.faces.len(), failed_faces))
    };
    let (mesh, faces, failed_faces) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(run))
        .unwrap_or_else(|p| {
        if p.is::<Cancelled>() {
            return Err(ShellFailure::Cancelled);
        }
        if p.is::<OutOfEvaluations>() {
            let surface = budget_slot
                .get()
                .and_then(|b| b.ran_over())
                .map(|debug| what_ran_over(&debug))
                .unwrap_or_else(|| "a face".to_string());
            return Err(ShellFailure::Diverged { surface });
        }
        let what = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".to_string());
        Err(ShellFailure::Panicked(what))
    })?;
    let open_edges = mesh.open_edges();
    if open_edges > 0 || mesh.triangles.is_empty() {
        return Err(ShellFailure::Open {
            open_edges,
            triangles: mesh.triangles.len(),
            faces,
            failed_faces,
        });
    }
    // Facing outwards whatever the file's orientation (the caller turns void shells inside out).
    let volume = mesh.volume();
    if volume > 0.0 {
        Ok(mesh)
    } else if volume < 0.0 {
        Ok(mesh.flipped())
    } else {
        Err(ShellFailure::NoVolume)
    }
}

/// `shell` with every face's surface and every edge's curve divided under `budget`.
fn guarded(
    shell: CompressedShell<Point3, Curve3D, Surface>,
    budget: &std::sync::Arc<DivisionBudget>,
) -> CompressedShell<Point3, GuardedCurve, Guarded> {
    CompressedShell {
        vertices: shell.vertices,
        edges: shell
            .edges
            .into_iter()
            .map(|edge| CompressedEdge {
                vertices: edge.vertices,
                curve: GuardedCurve::new(edge.curve, budget.clone()),
            })
            .collect(),
        faces: shell
            .faces
            .into_iter()
            .enumerate()
            .map(|(i, face)| CompressedFace {
                boundaries: face.boundaries,
                orientation: face.orientation,
                surface: Guarded::new(face.surface, i, budget.clone()),
            })
            .collect(),
    }
}

/// truck's polygon mesh as indexed triangles with positions closer than `weld` (file units) made
/// one (truck repeats a position per face, sometimes a few ulps apart; welding them is what lets
/// [`ShellMesh::open_edges`] see the seams). Degenerate triangles left by welding are dropped.
fn to_mesh(poly: &PolygonMesh, weld: f64) -> ShellMesh {
    let mut welder = Welder::new(weld);
    let triangles = welder.triangles(poly);
    ShellMesh {
        vertices: welder.vertices,
        triangles,
    }
}

/// Two corners of `t` are one vertex.
fn is_degenerate(t: [u32; 3]) -> bool {
    t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
}

/// Positions made one vertex when closer than `weld`, through a hash of cells `weld` wide.
struct Welder {
    weld: f64,
    cells: HashMap<[i64; 3], Vec<u32>>,
    vertices: Vec<DVec3>,
}

impl Welder {
    fn new(weld: f64) -> Welder {
        Welder {
            weld,
            cells: HashMap::new(),
            vertices: Vec::new(),
        }
    }

    /// The vertex at `v`: one within `weld` of it, or a new one.
    fn index(&mut self, v: DVec3) -> u32 {
        let cell = (v / self.weld).floor().as_i64vec3().to_array();
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    // Saturating: a position far beyond any part (a malformed file's 1e300)
                    // floors to the ends of i64 (fuzz target `step`, input 18,909 of seed 0x5EED).
                    let key = [
                        cell[0].saturating_add(dx),
                        cell[1].saturating_add(dy),
                        cell[2].saturating_add(dz),
                    ];
                    if let Some(list) = self.cells.get(&key) {
                        if let Some(&i) = list
                            .iter()
                            .find(|&&i| self.vertices[i as usize].distance(v) <= self.weld)
                        {
                            return i;
                        }
                    }
                }
            }
        }
        self.vertices.push(v);
        let i = (self.vertices.len() - 1) as u32;
        self.cells.entry(cell).or_default().push(i);
        i
    }

    /// The triangles of `poly` over the welded vertices, those welding made degenerate dropped.
    fn triangles(&mut self, poly: &PolygonMesh) -> Vec<[u32; 3]> {
        let index: Vec<u32> = poly
            .positions()
            .iter()
            .map(|p| self.index(DVec3::new(p.x, p.y, p.z)))
            .collect();
        poly.faces()
            .triangle_iter()
            .map(|t| [index[t[0].pos], index[t[1].pos], index[t[2].pos]])
            .filter(|t| !is_degenerate(*t))
            .collect()
    }
}

/// The shell's triangles, welded, face by face: truck's where they cover the face (the edges its
/// triangles use once are exactly the segments of the face's boundary polylines), else the face
/// laid out by [`crate::fill::rectangle_face`] where it can be, turned to run its edges against
/// its neighbours'. Returns the mesh and the surface kind of each face still not covered (left as
/// truck made it: the shell will not close).
///
/// Unwinds with [`crate::guard::Cancelled`] between faces once `cancelled` is set.
fn assemble(
    triangulated: &CompressedShell<Point3, PolylineCurve<Point3>, Option<PolygonMesh>>,
    surfaces: &[&Guarded],
    weld: f64,
    max_triangles: usize,
    cancelled: &AtomicBool,
) -> (ShellMesh, Vec<String>) {
    let mut welder = Welder::new(weld);
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut laid_out: Vec<Vec<[u32; 3]>> = Vec::new();
    let mut failed = Vec::new();
    for (face, surface) in triangulated.faces.iter().zip(surfaces) {
        unwind_if_cancelled(cancelled);
        let own: Vec<[u32; 3]> = match &face.surface {
            Some(poly) if face.orientation => welder.triangles(poly),
            Some(poly) => welder.triangles(&poly.inverse()),
            None => Vec::new(),
        };
        let loops: Vec<Vec<DVec3>> = face
            .boundaries
            .iter()
            .map(|wire| loop_points(triangulated, wire))
            .collect();
        if !own.is_empty() && covers(&own, &loops, &mut welder) {
            triangles.extend(own);
            continue;
        }
        let filled = match loops.as_slice() {
            [boundary] => crate::fill::rectangle_face(*surface, boundary, max_triangles),
            _ => None,
        };
        match filled {
            Some(face_triangles) => laid_out.push(
                face_triangles
                    .iter()
                    .map(|t| t.map(|p| welder.index(p)))
                    .filter(|t| !is_degenerate(*t))
                    .collect(),
            ),
            None => {
                failed.push(surface_kind(&format!("{:?}", surface.surface())));
                triangles.extend(own);
            }
        }
    }
    // Each face laid out here turned to run its edges against its neighbours' (a face alone, like
    // a whole torus, is turned with the shell by its volume's sign).
    let mut directed: HashSet<(u32, u32)> = HashSet::new();
    let add_edges = |tris: &[[u32; 3]], directed: &mut HashSet<(u32, u32)>| {
        for t in tris {
            for k in 0..3 {
                directed.insert((t[k], t[(k + 1) % 3]));
            }
        }
    };
    add_edges(&triangles, &mut directed);
    for mut face in laid_out {
        let (mut same, mut against) = (0, 0);
        for t in &face {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                same += usize::from(directed.contains(&(a, b)));
                against += usize::from(directed.contains(&(b, a)));
            }
        }
        if same > against {
            for t in &mut face {
                t.swap(1, 2);
            }
        }
        add_edges(&face, &mut directed);
        triangles.extend(face);
    }
    (
        ShellMesh {
            vertices: welder.vertices,
            triangles,
        },
        failed,
    )
}

/// Whether the edges `triangles` use once are exactly the segments of `loops` (welded by
/// `welder`): the face is covered, with no hole and nothing beyond its boundary.
fn covers(triangles: &[[u32; 3]], loops: &[Vec<DVec3>], welder: &mut Welder) -> bool {
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            *uses.entry(key(t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut boundary: HashSet<(u32, u32)> = HashSet::new();
    for l in loops {
        let index: Vec<u32> = l.iter().map(|&p| welder.index(p)).collect();
        for k in 0..index.len() {
            let (a, b) = (index[k], index[(k + 1) % index.len()]);
            if a != b {
                boundary.insert(key(a, b));
            }
        }
    }
    let once: HashSet<(u32, u32)> = uses
        .into_iter()
        .filter(|&(_, n)| n == 1)
        .map(|(e, _)| e)
        .collect();
    once == boundary
}

/// The points of boundary wire `wire` of a face of `shell`, in order, each edge's polyline
/// joined to the next (the joint once; the last point not repeating the first).
fn loop_points(
    shell: &CompressedShell<Point3, PolylineCurve<Point3>, Option<PolygonMesh>>,
    wire: &[CompressedEdgeIndex],
) -> Vec<DVec3> {
    let mut points: Vec<DVec3> = Vec::new();
    for e in wire {
        let Some(edge) = shell.edges.get(e.index) else {
            return Vec::new();
        };
        let mut line: Vec<DVec3> = edge
            .curve
            .iter()
            .map(|p| DVec3::new(p.x, p.y, p.z))
            .collect();
        if !e.orientation {
            line.reverse();
        }
        let skip = usize::from(points.last().is_some_and(|p| Some(p) == line.first()));
        points.extend_from_slice(&line[skip.min(line.len())..]);
    }
    if points.len() > 1 && points.first() == points.last() {
        points.pop();
    }
    points
}

/// The STEP-like name of a surface from its debug text: the first word naming a surface
/// (`ElementarySurface(ConicalSurface(...))` → `ConicalSurface`), or `surface`.
fn surface_kind(debug: &str) -> String {
    debug
        .split(|c: char| !c.is_ascii_alphanumeric())
        .find(|w| {
            w.ends_with("Surface") && *w != "ElementarySurface" || *w == "Plane" || *w == "Sphere"
        })
        .map(|w| match w {
            "Sphere" => "SphericalSurface".to_string(),
            other => other.to_string(),
        })
        .unwrap_or_else(|| "surface".to_string())
}

/// `a face on its NurbsSurface` or `an edge on its NurbsCurve`, from the debug text of what ran
/// over the bounds of [`crate::guard`].
fn what_ran_over(debug: &str) -> String {
    let curve = debug
        .split(|c: char| !c.is_ascii_alphanumeric())
        .find(|w| w.ends_with("Curve"));
    match curve {
        Some(kind) if !debug.contains("Surface") => format!("an edge on its {kind}"),
        _ => format!("a face on its {}", surface_kind(debug)),
    }
}

/// The diagonal of the points' bounding box (0 for none).
fn bounds_diagonal(points: &[DVec3]) -> f64 {
    let Some(first) = points.first() else {
        return 0.0;
    };
    let (lo, hi) = points
        .iter()
        .fold((*first, *first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    (hi - lo).length()
}
