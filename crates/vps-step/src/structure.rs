//! What a STEP file's entity graph says beyond the geometry: the length unit, which B-rep solids
//! it holds (with their void shells and names), and where an assembly places each of them.
//!
//! Read from the parsed instances directly (the geometry kernel ignores all three). Every walk is
//! bounded: assembly depth by [`MAX_ASSEMBLY_DEPTH`], placed copies by [`MAX_PLACED_SOLIDS`], unit
//! conversions by a depth of 8.

use std::collections::HashMap;

use glam::{DMat4, DVec3, DVec4};
use ruststep::ast::{EntityInstance, Name, Parameter, Record};

use crate::p21::Instances;
use crate::StepError;

/// The deepest assembly (parts in sub-assemblies in ...) followed; deeper, or a cycle, is an error.
pub const MAX_ASSEMBLY_DEPTH: usize = 16;
/// The most placed solids (instances of solids in an assembly) one file may yield.
pub const MAX_PLACED_SOLIDS: usize = 10_000;

/// The file's length unit.
#[derive(Clone, Debug, PartialEq)]
pub struct LengthUnit {
    /// Its name as the file gives it (`millimetre`, `inch`, `metre`, ...).
    pub name: String,
    /// Metres per file unit.
    pub metres: f64,
}

/// One B-rep solid of the file.
#[derive(Clone, Debug)]
pub struct Solid {
    /// The `MANIFOLD_SOLID_BREP` / `BREP_WITH_VOIDS` instance.
    pub id: u64,
    /// The solid's own name (may be empty).
    pub name: String,
    /// The name of the product whose shape it is, where the file links one.
    pub product: Option<String>,
    /// The outer `CLOSED_SHELL`.
    pub outer: u64,
    /// Void shells (`CLOSED_SHELL` ids), to be turned inside out.
    pub voids: Vec<u64>,
    /// Where each placed copy of the solid goes, in file units (one identity when not in an
    /// assembly).
    pub placements: Vec<DMat4>,
    /// The shape representation holding it, where one does.
    pub representation: Option<u64>,
}

/// A read-only view of the parsed instances.
pub struct Graph<'a> {
    instances: &'a Instances,
}

impl<'a> Graph<'a> {
    /// A view of `instances`.
    pub fn new(instances: &'a Instances) -> Self {
        Self { instances }
    }

    /// The records of instance `id` (one for a simple instance, several for a complex one).
    fn records(&self, id: u64) -> &'a [Record] {
        match self.instances.by_id.get(&id) {
            Some(EntityInstance::Simple { record, .. }) => std::slice::from_ref(record),
            Some(EntityInstance::Complex { subsuper, .. }) => &subsuper.0,
            None => &[],
        }
    }

    /// The record named `name` of instance `id`.
    fn record(&self, id: u64, name: &str) -> Option<&'a Record> {
        self.records(id).iter().find(|r| r.name == name)
    }

    /// The parameters of the record named `name` of instance `id`.
    fn params(&self, id: u64, name: &str) -> Option<&'a [Parameter]> {
        self.record(id, name).map(params)
    }

    /// Instance ids in file-number order.
    fn ids(&self) -> Vec<u64> {
        let mut ids: Vec<u64> = self.instances.by_id.keys().copied().collect();
        ids.sort_unstable();
        ids
    }

    /// The line instance `id` starts on, for errors.
    pub fn line(&self, id: u64) -> Option<usize> {
        self.instances.line_of.get(&id).copied()
    }

    /// The length unit of `solids`: the one the `GLOBAL_UNIT_ASSIGNED_CONTEXT`s of their shape
    /// representations name (other contexts, such as a PMI presentation's in inches beside a
    /// part in millimetres, are not asked), or of every context in the file when no solid's
    /// representation names one. Several different ones (a mixed-unit assembly) or none is an
    /// error.
    pub fn length_unit(&self, solids: &[Solid]) -> Result<LengthUnit, StepError> {
        let mut contexts: Vec<u64> = solids
            .iter()
            .filter_map(|s| {
                let rep = s.representation?;
                self.records(rep)
                    .iter()
                    .find(|r| r.name.ends_with("REPRESENTATION"))
                    .and_then(|r| params(r).get(2).and_then(reference))
            })
            .filter(|&c| self.record(c, "GLOBAL_UNIT_ASSIGNED_CONTEXT").is_some())
            .collect();
        contexts.sort_unstable();
        contexts.dedup();
        if contexts.is_empty() {
            contexts = self.ids();
        }
        let mut found: Vec<(LengthUnit, u64)> = Vec::new();
        for id in contexts {
            let Some(p) = self.params(id, "GLOBAL_UNIT_ASSIGNED_CONTEXT") else {
                continue;
            };
            for unit in refs(p.first()) {
                if self.record(unit, "LENGTH_UNIT").is_none() {
                    continue;
                }
                let u = self.unit_of(unit, 0).ok_or_else(|| {
                    StepError::format(
                        self.line(unit),
                        format!(
                            "length unit #{unit} is neither an SI unit nor a conversion of one"
                        ),
                    )
                })?;
                if !found.iter().any(|(f, _)| f.metres == u.metres) {
                    found.push((u, unit));
                }
            }
        }
        match found.len() {
            0 => Err(StepError::format(
                None,
                "the file names no length unit (no GLOBAL_UNIT_ASSIGNED_CONTEXT with a LENGTH_UNIT)",
            )),
            1 => Ok(found.remove(0).0),
            _ => Err(StepError::Unsupported {
                what: format!(
                    "several length units in one file ({}): mixed-unit assemblies are not read; \
                     export the assembly in one unit",
                    found
                        .iter()
                        .map(|(u, id)| format!("{} at #{id}", u.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                line: None,
            }),
        }
    }

    /// Metres per unit of length unit `id` (an `SI_UNIT` or a `CONVERSION_BASED_UNIT`).
    fn unit_of(&self, id: u64, depth: usize) -> Option<LengthUnit> {
        if depth > 8 {
            return None;
        }
        if let Some(p) = self.params(id, "SI_UNIT") {
            let prefix = match p.first() {
                Some(Parameter::Enumeration(e)) => Some(e.as_str()),
                _ => None,
            };
            let base = match p.get(1) {
                Some(Parameter::Enumeration(e)) => e.as_str(),
                _ => return None,
            };
            if base != "METRE" {
                return None;
            }
            let (factor, prefix_name) = match prefix {
                None => (1.0, ""),
                Some("MILLI") => (1e-3, "milli"),
                Some("CENTI") => (1e-2, "centi"),
                Some("DECI") => (1e-1, "deci"),
                Some("MICRO") => (1e-6, "micro"),
                Some("NANO") => (1e-9, "nano"),
                Some("KILO") => (1e3, "kilo"),
                Some(_) => return None,
            };
            return Some(LengthUnit {
                name: format!("{prefix_name}metre"),
                metres: factor,
            });
        }
        let p = self.params(id, "CONVERSION_BASED_UNIT")?;
        let name = string(p.first()).unwrap_or("unnamed").to_ascii_lowercase();
        let measure = reference(p.get(1)?)?;
        let m = self
            .records(measure)
            .iter()
            .find(|r| r.name.ends_with("MEASURE_WITH_UNIT"))
            .map(params)?;
        let value = real(m.first()?)?;
        let base = self.unit_of(reference(m.get(1)?)?, depth + 1)?;
        let metres = value * base.metres;
        (metres.is_finite() && metres > 0.0).then_some(LengthUnit { name, metres })
    }

    /// The smallest radius of any `SPHERICAL_SURFACE` (file units), if the file has one.
    pub fn smallest_sphere_radius(&self) -> Option<f64> {
        self.instances
            .by_id
            .keys()
            .filter_map(|&id| self.params(id, "SPHERICAL_SURFACE")?.get(2).and_then(real))
            .filter(|r| *r > 0.0)
            .reduce(f64::min)
    }

    /// Every B-rep solid of the file, in file order, with names and assembly placements.
    pub fn solids(&self) -> Result<Vec<Solid>, StepError> {
        let ids = self.ids();
        // Representation items → the representations holding them.
        let mut holders: HashMap<u64, Vec<u64>> = HashMap::new();
        for &id in &ids {
            for r in self.records(id) {
                if r.name.ends_with("REPRESENTATION") {
                    for item in refs(params(r).get(1)) {
                        holders.entry(item).or_default().push(id);
                    }
                }
            }
        }
        let links = Links::new(self, &ids)?;
        let products = self.product_names(&ids, &links);
        let mut solids = Vec::new();
        let mut placed = 0usize;
        for &id in &ids {
            let (p, voids) = if let Some(p) = self.params(id, "MANIFOLD_SOLID_BREP") {
                (p, Vec::new())
            } else if let Some(p) = self.params(id, "BREP_WITH_VOIDS") {
                let voids = refs(p.get(2))
                    .map(|v| {
                        self.params(v, "ORIENTED_CLOSED_SHELL")
                            .and_then(|o| o.get(2).and_then(reference))
                            .unwrap_or(v)
                    })
                    .collect();
                (p, voids)
            } else {
                continue;
            };
            let outer = p.get(1).and_then(reference).ok_or_else(|| {
                StepError::format(self.line(id), format!("solid #{id} names no outer shell"))
            })?;
            let reps = holders.get(&id).cloned().unwrap_or_default();
            let placements = match reps.first() {
                Some(&rep) => links.placements_of(rep)?,
                None => vec![DMat4::IDENTITY],
            };
            placed += placements.len();
            if placed > MAX_PLACED_SOLIDS {
                return Err(StepError::Unsupported {
                    what: format!("more than {MAX_PLACED_SOLIDS} placed solids"),
                    line: self.line(id),
                });
            }
            solids.push(Solid {
                id,
                name: string(p.first()).unwrap_or("").to_string(),
                product: reps
                    .iter()
                    .find_map(|&r| products.get(&links.class(r)).cloned()),
                outer,
                voids,
                placements,
                representation: reps.first().copied(),
            });
        }
        Ok(solids)
    }

    /// Product names by representation class: each `SHAPE_DEFINITION_REPRESENTATION` links a
    /// product's shape to a representation.
    fn product_names(&self, ids: &[u64], links: &Links) -> HashMap<u64, String> {
        let mut names = HashMap::new();
        for &id in ids {
            let Some(p) = self.params(id, "SHAPE_DEFINITION_REPRESENTATION") else {
                continue;
            };
            let (Some(pds), Some(rep)) =
                (p.first().and_then(reference), p.get(1).and_then(reference))
            else {
                continue;
            };
            if let Some(name) = self.product_of_shape(pds) {
                names.entry(links.class(rep)).or_insert(name);
            }
        }
        names
    }

    /// The name (or, when empty, the id) of the product a `PRODUCT_DEFINITION_SHAPE` describes.
    fn product_of_shape(&self, pds: u64) -> Option<String> {
        let pd = self
            .params(pds, "PRODUCT_DEFINITION_SHAPE")?
            .get(2)
            .and_then(reference)?;
        let formation = self
            .params(pd, "PRODUCT_DEFINITION")?
            .get(2)
            .and_then(reference)?;
        let product = self
            .records(formation)
            .iter()
            .find(|r| r.name.starts_with("PRODUCT_DEFINITION_FORMATION"))
            .map(params)?
            .get(2)
            .and_then(reference)?;
        let p = self.params(product, "PRODUCT")?;
        let name = string(p.get(1))
            .filter(|n| !n.is_empty())
            .or_else(|| string(p.first()))?;
        Some(name.to_string())
    }

    /// The frame of an `AXIS2_PLACEMENT_3D` as a matrix (columns: x, y, z axes and origin, file
    /// units), or `None` when `id` is not a usable one.
    fn frame(&self, id: u64) -> Option<DMat4> {
        let p = self.params(id, "AXIS2_PLACEMENT_3D")?;
        let origin = self.point(p.get(1).and_then(reference)?, "CARTESIAN_POINT")?;
        let z = match p.get(2).and_then(reference) {
            Some(d) => self.point(d, "DIRECTION")?.try_normalize()?,
            None => DVec3::Z,
        };
        let x_hint = match p.get(3).and_then(reference) {
            Some(d) => self.point(d, "DIRECTION")?,
            None => DVec3::X,
        };
        let x = (x_hint - z * x_hint.dot(z))
            .try_normalize()
            .or_else(|| z.any_orthonormal_vector().try_normalize())?;
        let y = z.cross(x);
        Some(DMat4::from_cols(
            x.extend(0.0),
            y.extend(0.0),
            z.extend(0.0),
            DVec4::new(origin.x, origin.y, origin.z, 1.0),
        ))
    }

    /// The coordinates of a `CARTESIAN_POINT` or `DIRECTION` (missing coordinates are 0).
    fn point(&self, id: u64, name: &str) -> Option<DVec3> {
        let p = self.params(id, name)?;
        let Some(Parameter::List(c)) = p.get(1) else {
            return None;
        };
        let mut v = [0.0; 3];
        for (k, x) in c.iter().take(3).enumerate() {
            v[k] = real(x)?;
        }
        let v = DVec3::from_array(v);
        v.is_finite().then_some(v)
    }
}

/// The links between shape representations: untransformed ones join representations into one
/// class (the same coordinates), transformed ones place a child class in a parent class.
struct Links {
    /// Union-find parent per representation id.
    parent: HashMap<u64, u64>,
    /// (child representation, parent representation, child-to-parent transform).
    placed: Vec<(u64, u64, DMat4)>,
}

impl Links {
    fn new(graph: &Graph<'_>, ids: &[u64]) -> Result<Self, StepError> {
        let mut links = Links {
            parent: HashMap::new(),
            placed: Vec::new(),
        };
        for &id in ids {
            let Some(p) = graph
                .params(id, "REPRESENTATION_RELATIONSHIP")
                .or_else(|| graph.params(id, "SHAPE_REPRESENTATION_RELATIONSHIP"))
            else {
                continue;
            };
            let (Some(child), Some(parent)) =
                (p.get(2).and_then(reference), p.get(3).and_then(reference))
            else {
                continue;
            };
            let transform = graph
                .params(id, "REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION")
                .and_then(|t| t.first().and_then(reference));
            match transform {
                None => links.union(child, parent),
                Some(t) => {
                    // transform_item_1 is a frame in rep_1 (the component), transform_item_2
                    // the frame in rep_2 (the assembly) it is placed onto.
                    let m = graph
                        .params(t, "ITEM_DEFINED_TRANSFORMATION")
                        .and_then(|i| {
                            let in_component = graph.frame(i.get(2).and_then(reference)?)?;
                            let in_assembly = graph.frame(i.get(3).and_then(reference)?)?;
                            Some(in_assembly * in_component.inverse())
                        })
                        .ok_or_else(|| StepError::Unsupported {
                            what: format!(
                                "assembly link #{id}: its transformation #{t} is not an \
                                 ITEM_DEFINED_TRANSFORMATION between two AXIS2_PLACEMENT_3D"
                            ),
                            line: graph.line(id),
                        })?;
                    links.placed.push((child, parent, m));
                }
            }
        }
        Ok(links)
    }

    fn class(&self, mut id: u64) -> u64 {
        let mut steps = 0;
        while let Some(&p) = self.parent.get(&id) {
            if p == id || steps > self.parent.len() {
                break;
            }
            id = p;
            steps += 1;
        }
        id
    }

    fn union(&mut self, a: u64, b: u64) {
        let (ra, rb) = (self.class(a), self.class(b));
        if ra != rb {
            self.parent.insert(ra, rb);
        }
    }

    /// Every placement of representation `rep` in the root's coordinates.
    fn placements_of(&self, rep: u64) -> Result<Vec<DMat4>, StepError> {
        let mut known = HashMap::new();
        self.placements_in(self.class(rep), 0, &mut known)
    }

    /// The placements of representation class `class`, remembered in `known` so a shared
    /// sub-assembly is walked once.
    fn placements_in(
        &self,
        class: u64,
        depth: usize,
        known: &mut HashMap<u64, Vec<DMat4>>,
    ) -> Result<Vec<DMat4>, StepError> {
        if let Some(p) = known.get(&class) {
            return Ok(p.clone());
        }
        if depth > MAX_ASSEMBLY_DEPTH {
            return Err(StepError::Unsupported {
                what: format!(
                    "an assembly deeper than {MAX_ASSEMBLY_DEPTH} levels (or one that contains \
                     itself)"
                ),
                line: None,
            });
        }
        let mut out = Vec::new();
        for &(child, parent, m) in &self.placed {
            if self.class(child) != class {
                continue;
            }
            for above in self.placements_in(self.class(parent), depth + 1, known)? {
                out.push(above * m);
                if out.len() > MAX_PLACED_SOLIDS {
                    return Err(StepError::Unsupported {
                        what: format!("more than {MAX_PLACED_SOLIDS} placed solids"),
                        line: None,
                    });
                }
            }
        }
        if out.is_empty() {
            out.push(DMat4::IDENTITY);
        }
        known.insert(class, out.clone());
        Ok(out)
    }
}

/// A record's parameters (empty when it has none).
fn params(r: &Record) -> &[Parameter] {
    match &r.parameter {
        Parameter::List(p) => p,
        _ => &[],
    }
}

/// The instance a parameter refers to.
fn reference(p: &Parameter) -> Option<u64> {
    match p {
        Parameter::Ref(Name::Entity(id)) => Some(*id),
        _ => None,
    }
}

/// The instances a list parameter refers to.
fn refs(p: Option<&Parameter>) -> impl Iterator<Item = u64> + '_ {
    let list: &[Parameter] = match p {
        Some(Parameter::List(l)) => l,
        _ => &[],
    };
    list.iter().filter_map(reference)
}

/// A number (real, integer, or a typed one such as `LENGTH_MEASURE(25.4)`).
fn real(p: &Parameter) -> Option<f64> {
    match p {
        Parameter::Real(x) => Some(*x),
        Parameter::Integer(i) => Some(*i as f64),
        Parameter::Typed { parameter, .. } => real(parameter),
        _ => None,
    }
}

/// A string parameter.
fn string(p: Option<&Parameter>) -> Option<&str> {
    match p {
        Some(Parameter::String(s)) => Some(s),
        _ => None,
    }
}
