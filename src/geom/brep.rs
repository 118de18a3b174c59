//! Boundary representations: a shell of faces (surfaces cut to loops) whose loops are made of
//! edges the faces share — what STEP solids are. Meshing a shell discretises each edge once
//! and uses those samples in every face that runs along it, so faces meet without cracks
//! ([`crate::plan::plan_shell`]).

use super::analytic::Analytic;
use super::{BSplineCurve, BSplineSurface};
use crate::error::{Error, Result};
use glam::DVec3;

/// A shell: faces bounded by loops of shared edges between shared vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Shell {
    vertices: Vec<DVec3>,
    edges: Vec<Edge>,
    faces: Vec<Face>,
    closed: bool,
}

/// An edge: a curve from its start vertex to its end vertex over the curve's range
/// (`curve.point(range.start)` is the start vertex, within the file's precision).
#[derive(Clone, Debug, PartialEq)]
pub struct Edge {
    pub curve: BSplineCurve,
    pub start: usize,
    pub end: usize,
}

/// An edge as a loop runs along it: `forward` from its start to its end, else backwards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OrientedEdge {
    pub edge: usize,
    pub forward: bool,
}

/// One boundary of a face.
#[derive(Clone, Debug, PartialEq)]
pub enum Bound {
    /// A closed chain of edges, each starting where the one before ends.
    Edges(Vec<OrientedEdge>),
    /// A single vertex: an apex or pole the face reaches (no area of its own).
    Vertex(usize),
}

/// A face: part of `surface` inside its bounds. `same_sense`: the face's outward normal is
/// the surface's S_u × S_v (else its opposite); its bounds run counter-clockwise about that
/// normal (material on the left).
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    pub surface: BSplineSurface,
    pub same_sense: bool,
    pub bounds: Vec<Bound>,
    /// What the file calls the face (e.g. "ADVANCED_FACE #42"), for errors.
    pub name: String,
    /// The exact shape `surface` converts, where the file names one the mesher has a
    /// closed-form deviation for (see [`Analytic`]).
    pub shape: Option<Analytic>,
    /// Where some of its edges run in `surface`'s parameters, as the file draws them there
    /// (pcurves); at most one per edge.
    pub traces: Vec<EdgeTrace>,
}

/// Where an edge runs in a face's parameters: points of the face's (u, v) along it, as the
/// file's curve in the parameter domain (a pcurve) gives them, in no particular order. The
/// mesher starts the inversion of each of the edge's points onto the face from the trace's
/// point nearest it in model space, so the point takes the sheet, the side of a seam and
/// the parameter at a pole that the file meant, where the edge alone is ambiguous.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeTrace {
    pub edge: usize,
    pub params: Vec<glam::DVec2>,
}

impl Shell {
    /// Checks that every index is in range and that each loop is a chain: every edge starts
    /// at the vertex where the one before it ends (as the loop runs), the last ends where the
    /// first starts. `closed`: the shell bounds a solid (a closed shell), so every edge is run
    /// along by faces exactly twice, once each way — else the error names the edge.
    pub fn try_new(
        vertices: Vec<DVec3>,
        edges: Vec<Edge>,
        faces: Vec<Face>,
        closed: bool,
    ) -> Result<Self> {
        let invalid = |what: String| Error::InvalidBrep { what };
        for (k, edge) in edges.iter().enumerate() {
            if edge.start >= vertices.len() || edge.end >= vertices.len() {
                return Err(invalid(format!(
                    "edge {k} names a vertex that does not exist"
                )));
            }
        }
        let mut uses = vec![[0u32; 2]; edges.len()];
        for face in &faces {
            if let Some(trace) = face.traces.iter().find(|t| t.edge >= edges.len()) {
                return Err(invalid(format!(
                    "{}: a trace names edge {}, which does not exist",
                    face.name, trace.edge
                )));
            }
            for (b, bound) in face.bounds.iter().enumerate() {
                let chain = match bound {
                    Bound::Vertex(v) if *v < vertices.len() => continue,
                    Bound::Vertex(_) => {
                        return Err(invalid(format!(
                            "{}: bound {b} names a vertex that does not exist",
                            face.name
                        )));
                    }
                    Bound::Edges(chain) => chain,
                };
                if chain.is_empty() {
                    return Err(invalid(format!("{}: bound {b} has no edges", face.name)));
                }
                let ends = |o: &OrientedEdge| -> Result<(usize, usize)> {
                    let edge = edges.get(o.edge).ok_or_else(|| {
                        invalid(format!(
                            "{}: bound {b} names an edge that does not exist",
                            face.name
                        ))
                    })?;
                    Ok(if o.forward {
                        (edge.start, edge.end)
                    } else {
                        (edge.end, edge.start)
                    })
                };
                for (k, o) in chain.iter().enumerate() {
                    let (_, end) = ends(o)?;
                    let (next_start, _) = ends(&chain[(k + 1) % chain.len()])?;
                    if end != next_start {
                        return Err(invalid(format!(
                            "{}: bound {b} is not a closed chain: its edge {k} ends at vertex {end}, the next starts at vertex {next_start}",
                            face.name
                        )));
                    }
                    uses[o.edge][usize::from(!o.forward)] += 1;
                }
            }
        }
        if closed && let Some(k) = uses.iter().position(|&u| u != [1, 1]) {
            return Err(invalid(format!(
                "the shell is declared closed, but edge {k} is run along {} times forwards and {} times backwards (once each way is needed)",
                uses[k][0], uses[k][1]
            )));
        }
        Ok(Shell {
            vertices,
            edges,
            faces,
            closed,
        })
    }

    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }
    pub fn faces(&self) -> &[Face] {
        &self.faces
    }
    /// Whether the shell bounds a solid (its mesh is closed).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The shell with every point moved by the affine map `f` (which must keep orientation:
    /// a mirror would turn the faces inside out).
    pub fn mapped(&self, f: impl Fn(DVec3) -> DVec3 + Copy) -> Self {
        Shell {
            vertices: self.vertices.iter().map(|&p| f(p)).collect(),
            edges: self
                .edges
                .iter()
                .map(|e| Edge {
                    curve: e.curve.mapped(f),
                    ..e.clone()
                })
                .collect(),
            faces: self
                .faces
                .iter()
                .map(|face| Face {
                    surface: face.surface.mapped(f),
                    shape: face.shape.and_then(|shape| shape.mapped(f)),
                    ..face.clone()
                })
                .collect(),
            closed: self.closed,
        }
    }

    /// The shell turned inside out (a void's shell as its solid sees it): every face's
    /// sense flipped, its loops run the other way.
    pub fn reversed(&self) -> Shell {
        let faces = self
            .faces
            .iter()
            .map(|f| Face {
                same_sense: !f.same_sense,
                bounds: f
                    .bounds
                    .iter()
                    .map(|b| match b {
                        Bound::Vertex(v) => Bound::Vertex(*v),
                        Bound::Edges(chain) => Bound::Edges(
                            chain
                                .iter()
                                .rev()
                                .map(|o| OrientedEdge {
                                    edge: o.edge,
                                    forward: !o.forward,
                                })
                                .collect(),
                        ),
                    })
                    .collect(),
                ..f.clone()
            })
            .collect();
        Shell {
            faces,
            ..self.clone()
        }
    }

    /// Bounding box (min, max) of the faces' control points.
    pub fn control_box(&self) -> (DVec3, DVec3) {
        self.faces.iter().fold(
            (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(low, high), face| {
                let (a, b) = face.surface.control_box();
                (low.min(a), high.max(b))
            },
        )
    }
}
