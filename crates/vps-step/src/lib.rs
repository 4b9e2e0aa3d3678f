//! STEP files (ISO 10303-21: the B-rep solids of AP203, AP214 and AP242) as triangle meshes in
//! metres.
//!
//! [`read_step`] reads a file's length unit, finds its B-rep solids (`MANIFOLD_SOLID_BREP`,
//! `BREP_WITH_VOIDS`), their names and product names, places each copy an assembly makes
//! (`ITEM_DEFINED_TRANSFORMATION` links between shape representations), and triangulates each
//! shell within a chord tolerance with the truck kernel. Every solid returned is closed and
//! consistently oriented (checked: every directed edge once, its reverse once, positive volume);
//! a solid that cannot be meshed so fails with a [`StepError`] naming it and the reason. Nothing
//! approximate is returned silently.
//!
//! Not read: open shells and surface models (`SHELL_BASED_SURFACE_MODEL`), faceted and tessellated
//! (AP242 `TESSELLATED_SOLID`) representations, mixed-unit assemblies, external references.
//!
//! - [`p21`]: the exchange structure cut into entity instances (bounded, no recursion).
//! - [`structure`]: units, solids, names and assembly placements from the entity graph.
//! - [`tessellate`]: one shell to checked triangles.
//! - [`guard`]: bounds on the kernel's subdivision and evaluations (malformed B-splines fail fast),
//!   and the read's deadline.
//! - `fill`: faces the kernel leaves empty laid out by vps where their boundary is a rectangle in
//!   the surface's parameters (a cone to its apex, a whole torus).
//!
//! Reading allocates and may take seconds for large files: setup work, never frame-path work.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

mod fill;
pub mod guard;
pub mod p21;
pub mod structure;
pub mod tessellate;

use std::collections::HashMap;

use glam::DVec3;
use truck_stepio::r#in::Table;

pub use structure::LengthUnit;

/// How to read a STEP file.
#[derive(Clone, Debug, PartialEq)]
pub struct StepOptions {
    /// Largest distance between a triangle and the exact surface (m), > 0.
    pub chord_tolerance: f64,
    /// Read only the solids with these names (a solid's own name or its product's name); `None`
    /// reads every solid. Each name must match at least one solid.
    pub solids: Option<Vec<String>>,
    /// The most triangles one solid may need (estimated before the fine pass).
    pub max_triangles: usize,
    /// The longest the geometry kernel may take to tessellate the file's solids: a backstop, as
    /// [`guard`] bounds the kernel's subdivision and evaluations (malformed B-spline geometry made
    /// truck loop for ever before it). Past this the read fails and the kernel's thread is left to
    /// finish (or run until the process exits).
    pub deadline: std::time::Duration,
}

impl StepOptions {
    /// Every solid, at `chord_tolerance` (m), at most 20 million triangles each, within 120 s.
    pub fn new(chord_tolerance: f64) -> Self {
        Self {
            chord_tolerance,
            solids: None,
            max_triangles: 20_000_000,
            deadline: std::time::Duration::from_secs(120),
        }
    }
}

/// One placed solid, in metres.
#[derive(Clone, Debug)]
pub struct StepSolid {
    /// The solid's name, or its product's name where the solid has none, or `#ID`.
    pub name: String,
    /// The instance number of its `MANIFOLD_SOLID_BREP` / `BREP_WITH_VOIDS`.
    pub id: u64,
    /// Vertex positions (m).
    pub vertices: Vec<DVec3>,
    /// Triangles, counter-clockwise seen from outside (void shells face inwards).
    pub triangles: Vec<[u32; 3]>,
}

impl StepSolid {
    /// The enclosed volume (m³): outer shell less voids.
    pub fn volume(&self) -> f64 {
        tessellate::enclosed_volume(&self.vertices, &self.triangles)
    }
}

/// What a STEP file held.
#[derive(Clone, Debug)]
pub struct StepModel {
    /// The file's length unit.
    pub unit: LengthUnit,
    /// Every selected solid, one per placed copy, in file order.
    pub solids: Vec<StepSolid>,
    /// Every solid of the file by name (before selection), for messages.
    pub names: Vec<String>,
    /// Entity instances the STEP grammar could not read and that no selected solid needed
    /// (presentation and PMI entities, mostly).
    pub unread_instances: usize,
}

/// Why a STEP file was refused. Its text is `line N: ` (where the line is known) followed by
/// [`StepError::detail`].
#[derive(Debug)]
pub enum StepError {
    /// The exchange structure is malformed.
    Format {
        /// 1-based line, where known.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// The file uses something this reader does not handle.
    Unsupported {
        /// What.
        what: String,
        /// 1-based line, where known.
        line: Option<usize>,
    },
    /// A solid could not be meshed.
    Solid {
        /// Its name.
        name: String,
        /// Its instance number.
        id: u64,
        /// Its line.
        line: Option<usize>,
        /// Why.
        reason: String,
    },
    /// The options or the selection do not fit the file.
    Selection(String),
    /// The tessellation did not finish within [`StepOptions::deadline`] (a backstop: the bounds of
    /// [`guard`] stop every malformed surface seen so far long before it). Its thread stops at its
    /// next surface evaluation or edge division.
    Deadline {
        /// The deadline (s).
        seconds: f64,
    },
}

impl StepError {
    /// A [`StepError::Format`].
    pub fn format(line: Option<usize>, message: impl Into<String>) -> Self {
        Self::Format {
            line,
            message: message.into(),
        }
    }

    /// The 1-based line of the file the error is about, where known.
    pub fn line(&self) -> Option<usize> {
        match self {
            Self::Format { line, .. }
            | Self::Unsupported { line, .. }
            | Self::Solid { line, .. } => *line,
            Self::Selection(_) | Self::Deadline { .. } => None,
        }
    }

    /// What is wrong, without the line (for a caller that reports the line itself).
    pub fn detail(&self) -> String {
        match self {
            Self::Format { message, .. } => message.clone(),
            Self::Unsupported { what, .. } => format!("not supported: {what}"),
            Self::Solid {
                name, id, reason, ..
            } => format!("solid '{name}' (#{id}): {reason}"),
            Self::Selection(message) => message.clone(),
            Self::Deadline { seconds } => format!(
                "the geometry kernel (truck) did not finish tessellating the file's solids within \
                 {seconds} s: check the file in a CAD tool, or export the part as STL"
            ),
        }
    }
}

impl std::fmt::Display for StepError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(line) = self.line() {
            write!(f, "line {line}: ")?;
        }
        f.write_str(&self.detail())
    }
}

impl std::error::Error for StepError {}

/// What a STEP file's entity graph says, before any geometry is tessellated: its unit, solids
/// (selected by name), names and placements. [`read_step`] tessellates from it.
pub struct StepStructure {
    /// The file's length unit.
    pub unit: LengthUnit,
    /// Every solid of the file by name, for messages.
    pub names: Vec<String>,
    /// The selected solids with their display names.
    pub selected: Vec<(String, structure::Solid)>,
    /// The parsed entity instances.
    pub instances: p21::Instances,
}

/// Reads a STEP file's structure (see [`StepStructure`]) and selects `solids` (by a solid's or
/// its product's name; `None`: all). Bounded work: one pass over the bytes, no recursion deeper
/// than [`p21::MAX_DEPTH`], assemblies bounded by [`structure::MAX_ASSEMBLY_DEPTH`] and
/// [`structure::MAX_PLACED_SOLIDS`].
pub fn read_structure(bytes: &[u8], solids: Option<&[String]>) -> Result<StepStructure, StepError> {
    let text = String::from_utf8_lossy(bytes);
    let raw = p21::split_instances(&text)?;
    let instances = p21::parse_instances(&raw);
    drop(raw);
    let graph = structure::Graph::new(&instances);
    let all = graph.solids()?;
    if all.is_empty() {
        return Err(StepError::Unsupported {
            what: "the file holds no B-rep solid (MANIFOLD_SOLID_BREP or BREP_WITH_VOIDS); \
                   surface models and tessellated shapes are not read"
                .to_string(),
            line: None,
        });
    }
    let unit = graph.length_unit(&all)?;
    let display = |s: &structure::Solid| -> String {
        if !s.name.is_empty() {
            s.name.clone()
        } else {
            s.product.clone().unwrap_or_else(|| format!("#{}", s.id))
        }
    };
    let names: Vec<String> = all.iter().map(display).collect();
    let matches = |s: &structure::Solid, w: &String| &s.name == w || s.product.as_ref() == Some(w);
    if let Some(wanted) = solids {
        if let Some(w) = wanted.iter().find(|w| !all.iter().any(|s| matches(s, w))) {
            return Err(StepError::Selection(format!(
                "no solid named '{w}'; the file's solids: {}",
                names.join(", ")
            )));
        }
    }
    let selected = all
        .into_iter()
        .filter(|s| solids.is_none_or(|wanted| wanted.iter().any(|w| matches(s, w))))
        .map(|s| (display(&s), s))
        .collect();
    Ok(StepStructure {
        unit,
        names,
        selected,
        instances,
    })
}

/// Reads the B-rep solids of a STEP file's bytes as triangle meshes in metres (see the crate
/// documentation). Blocking CPU work; allocates about the file's size plus the meshes. The
/// tessellation runs on a thread of its own, bounded by [`StepOptions::deadline`].
pub fn read_step(bytes: &[u8], options: &StepOptions) -> Result<StepModel, StepError> {
    if !(options.chord_tolerance.is_finite() && options.chord_tolerance > 0.0) {
        return Err(StepError::Selection(format!(
            "the chord tolerance must be a positive length, got {} m",
            options.chord_tolerance
        )));
    }
    let StepStructure {
        unit,
        names,
        selected,
        instances,
    } = read_structure(bytes, options.solids.as_deref())?;
    let graph = structure::Graph::new(&instances);
    let mut table = Table::default();
    for instance in instances.by_id.values() {
        // An instance truck cannot read only matters if a selected solid needs it; converting
        // that solid then fails and says so.
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            table.push_instance(instance)
        }));
    }
    let tolerance = options.chord_tolerance / unit.metres;
    let coarse_limit = graph.smallest_sphere_radius().unwrap_or(f64::INFINITY) * 0.5;
    let mut needed: Vec<u64> = selected
        .iter()
        .flat_map(|(_, s)| std::iter::once(s.outer).chain(s.voids.iter().copied()))
        .collect();
    needed.sort_unstable();
    needed.dedup();
    let max_triangles = options.max_triangles;
    let (send, receive) = std::sync::mpsc::channel();
    // Set at the deadline: the thread's tessellation stops at its next surface evaluation or edge
    // division (every one goes through `guard`), so a read given up on does not run on.
    let cancelled = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let cancel = cancelled.clone();
    std::thread::Builder::new()
        .name("vps-step tessellate".into())
        .spawn(move || {
            let shells: HashMap<u64, Result<tessellate::ShellMesh, tessellate::ShellFailure>> =
                needed
                    .into_iter()
                    .map(|id| {
                        let mesh = tessellate::shell(
                            &table,
                            id,
                            tolerance,
                            coarse_limit,
                            max_triangles,
                            &cancel,
                        );
                        (id, mesh)
                    })
                    .collect();
            let _ = send.send(shells);
        })
        .map_err(|e| StepError::Unsupported {
            what: format!("cannot start the tessellating thread: {e}"),
            line: None,
        })?;
    let shells = receive.recv_timeout(options.deadline).map_err(|_| {
        cancelled.store(true, std::sync::atomic::Ordering::Relaxed);
        StepError::Deadline {
            seconds: options.deadline.as_secs_f64(),
        }
    })?;
    let mut solids = Vec::new();
    for (name, s) in &selected {
        for &shell in std::iter::once(&s.outer).chain(&s.voids) {
            if let Some(Err(e)) = shells.get(&shell) {
                let reason = match e {
                    &tessellate::ShellFailure::TooMany { triangles } => format!(
                        "at a chord tolerance of {} m it needs about {triangles} triangles, \
                         over the limit of {}: use a coarser tolerance",
                        options.chord_tolerance, options.max_triangles
                    ),
                    other if names.len() > 1 => format!(
                        "shell #{shell}: {other}; export this solid as STL from the CAD tool, or \
                         read the others with `solids = [...]` (the file's solids: {})",
                        names.join(", ")
                    ),
                    other => format!(
                        "shell #{shell}: {other}; export it as STL from the CAD tool instead"
                    ),
                };
                return Err(StepError::Solid {
                    name: name.clone(),
                    id: s.id,
                    line: graph.line(s.id),
                    reason,
                });
            }
        }
    }
    let shells: HashMap<u64, tessellate::ShellMesh> = shells
        .into_iter()
        .filter_map(|(id, m)| m.ok().map(|m| (id, m)))
        .collect();
    for (name, s) in &selected {
        for placement in &s.placements {
            let mut vertices = Vec::new();
            let mut triangles = Vec::new();
            for (k, &shell) in std::iter::once(&s.outer).chain(&s.voids).enumerate() {
                let mesh = &shells[&shell];
                let base = vertices.len() as u32;
                vertices.extend(
                    mesh.vertices
                        .iter()
                        .map(|&v| placement.transform_point3(v) * unit.metres),
                );
                // Void shells are written facing out of the void; the solid's surface there faces
                // into it.
                triangles.extend(mesh.triangles.iter().map(|t| {
                    let t = t.map(|i| i + base);
                    if k == 0 {
                        t
                    } else {
                        [t[0], t[2], t[1]]
                    }
                }));
            }
            if placement.determinant() < 0.0 {
                triangles.iter_mut().for_each(|t| t.swap(1, 2));
            }
            solids.push(StepSolid {
                name: name.clone(),
                id: s.id,
                vertices,
                triangles,
            });
        }
    }
    Ok(StepModel {
        unit,
        solids,
        names,
        unread_instances: instances.refused.len(),
    })
}
