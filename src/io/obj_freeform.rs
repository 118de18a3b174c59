//! Reader for Wavefront OBJ free-form geometry (`cstype`, `deg`, `surf`, `curv`, `parm`, `end`),
//! as Maya and Rhino write it.
//!
//! Rules: `v x y z [w]` is a Cartesian point with a separate weight (default 1); `cstype`
//! and `deg` are state that carries over to later elements; control-vertex lists run u
//! fastest and may use negative (relative) references; `parm` values are knots for `bspline`
//! and global breakpoints for `bezier`; a `\` at the end of a line continues it. Trimming:
//! `vp u v [w]` parameter vertices, `curv2` parameter-space curves over them, and in a
//! `surf` body `trim`/`hole` loops of `u0 u1 curv2` triples make a trimmed face (several
//! `trim` loops are kept as further loops: the face is what an odd number of loops
//! encloses); `scrv` special curves (the same triples, an open chain) and `sp` special points
//! (`vp` references) are edges and vertices the face's mesh must have — a surface with them
//! and no loop is a face of its whole range. Polygonal and display statements are ignored.

use crate::error::{Error, Result};
use crate::geom::{
    BSplineCurve, BSplineSurface, Interval, KnotVector, ParamMap, SpecialCurve, TrimLoop,
    TrimmedSurface,
};
use crate::scene::{Geometry, Item, Scene};
use glam::{DVec2, DVec3};

/// Parses OBJ text. Errors carry the 1-based line ([`Error::AtLine`]).
pub fn read_obj_freeform(text: &str) -> Result<Scene> {
    let mut reader = Reader::default();
    for (line, statement) in logical_lines(text) {
        reader.line = line;
        // Errors found at `end` already name the line of the statement at fault.
        reader.statement(&statement).map_err(|e| {
            if e.line().is_some() {
                e
            } else {
                e.at_line(line)
            }
        })?;
    }
    if let Some(element) = reader.element {
        return Err(
            Error::syntax(format!("`{}` element has no `end`", element.keyword()))
                .at_line(element.line),
        );
    }
    if reader.scene.items.is_empty() {
        return Err(Error::syntax(
            "no free-form surface or curve (`surf`/`curv` … `end`) in the file",
        ));
    }
    Ok(reader.scene)
}

/// Joins `\`-continued lines and strips comments; yields (first line number, statement).
fn logical_lines(text: &str) -> impl Iterator<Item = (usize, String)> + '_ {
    let mut lines = text.lines().enumerate();
    std::iter::from_fn(move || {
        let (index, first) = lines.next()?;
        let mut statement = String::new();
        let mut current = first;
        loop {
            let content = current.split('#').next().unwrap_or("").trim_end();
            match content.strip_suffix('\\') {
                Some(head) => {
                    statement.push_str(head);
                    statement.push(' ');
                    match lines.next() {
                        Some((_, next)) => current = next,
                        None => break,
                    }
                }
                None => {
                    statement.push_str(content);
                    break;
                }
            }
        }
        Some((index + 1, statement))
    })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Basis {
    Bezier,
    BSpline,
}

#[derive(Clone, Copy)]
struct CsType {
    rational: bool,
    basis: Basis,
}

enum Kind {
    Surface {
        range_u: Interval,
        range_v: Interval,
    },
    Curve {
        range: Interval,
    },
    /// A parameter-space curve (`curv2`) over `vp` points, for trimming loops.
    ParamCurve,
}

/// A trimming loop or special curve of a `surf` body: (u0, u1, `curv2` index) triples, and
/// whether it is a `hole`.
struct LoopStatement {
    hole: bool,
    line: usize,
    pieces: Vec<(f64, f64, usize)>,
}

struct Element {
    kind: Kind,
    line: usize,
    cstype: Option<CsType>,
    degrees: Option<(usize, Option<usize>)>,
    vertices: Vec<usize>,
    parm_u: Option<(usize, Vec<f64>)>,
    parm_v: Option<(usize, Vec<f64>)>,
    loops: Vec<LoopStatement>,
    /// `scrv` statements.
    special_curves: Vec<LoopStatement>,
    /// The `vp` of every `sp` reference.
    special_points: Vec<usize>,
}

impl Element {
    fn keyword(&self) -> &'static str {
        match self.kind {
            Kind::Surface { .. } => "surf",
            Kind::Curve { .. } => "curv",
            Kind::ParamCurve => "curv2",
        }
    }
}

#[derive(Default)]
struct Reader {
    scene: Scene,
    /// The current group (`g`): the name of the items that follow.
    group: Option<String>,
    /// Cartesian position and weight of every `v`.
    vertices: Vec<(DVec3, f64)>,
    /// (u, v) and weight of every `vp`.
    param_vertices: Vec<(DVec3, f64)>,
    /// Every `curv2`, in file order.
    param_curves: Vec<BSplineCurve>,
    cstype: Option<CsType>,
    degrees: Option<(usize, Option<usize>)>,
    element: Option<Element>,
    line: usize,
}

fn number(token: &str) -> Result<f64> {
    token
        .parse::<f64>()
        .map_err(|_| Error::syntax(format!("`{token}` is not a number")))
}

fn numbers(tokens: &[&str]) -> Result<Vec<f64>> {
    tokens.iter().map(|t| number(t)).collect()
}

/// Resolves a reference (`v[/vt[/vn]]`, a `vp` or a `curv2` index; negative: counted back)
/// to a 0-based index among the `available` defined above it.
fn resolve(reference: &str, available: usize) -> Result<usize> {
    let head = reference.split('/').next().unwrap_or("");
    let value: i64 = head
        .parse()
        .map_err(|_| Error::syntax(format!("`{reference}` is not a vertex reference")))?;
    let index = if value > 0 {
        value - 1
    } else {
        available as i64 + value
    };
    if value == 0 || index < 0 || index >= available as i64 {
        return Err(Error::VertexReference {
            reference: value,
            available,
        });
    }
    Ok(index as usize)
}

fn degree(token: &str) -> Result<usize> {
    let value: usize = token
        .parse()
        .map_err(|_| Error::syntax(format!("degree `{token}` is not a non-negative integer")))?;
    crate::geom::check_degree(value)?;
    Ok(value)
}

impl Reader {
    /// Adds an item named by the current group.
    fn push(&mut self, geometry: Geometry) {
        self.scene.items.push(Item {
            name: self.group.clone(),
            ..Item::new(geometry)
        });
    }

    fn statement(&mut self, statement: &str) -> Result<()> {
        let tokens: Vec<&str> = statement.split_whitespace().collect();
        let Some((&keyword, args)) = tokens.split_first() else {
            return Ok(());
        };
        if self.element.is_some() {
            return self.body_statement(keyword, args);
        }
        match keyword {
            "v" => {
                if !(3..=4).contains(&args.len()) {
                    return Err(Error::syntax(format!(
                        "`v` needs x y z [w], found {} values",
                        args.len()
                    )));
                }
                let values = numbers(args)?;
                self.vertices.push((
                    DVec3::new(values[0], values[1], values[2]),
                    values.get(3).copied().unwrap_or(1.0),
                ));
            }
            "vp" => {
                if !(1..=3).contains(&args.len()) {
                    return Err(Error::syntax(format!(
                        "`vp` needs u [v [w]], found {} values",
                        args.len()
                    )));
                }
                let values = numbers(args)?;
                self.param_vertices.push((
                    DVec3::new(values[0], values.get(1).copied().unwrap_or(0.0), 0.0),
                    values.get(2).copied().unwrap_or(1.0),
                ));
            }
            "cstype" => {
                let (rational, name) = match args {
                    ["rat", name] => (true, *name),
                    [name] => (false, *name),
                    _ => return Err(Error::syntax("`cstype` needs [rat] bezier|bspline")),
                };
                let basis = match name {
                    "bezier" => Basis::Bezier,
                    "bspline" => Basis::BSpline,
                    other => {
                        return Err(Error::syntax(format!(
                            "cstype `{other}` is not supported (bezier, bspline)"
                        )));
                    }
                };
                self.cstype = Some(CsType { rational, basis });
            }
            "deg" => {
                self.degrees = match args {
                    [du] => Some((degree(du)?, None)),
                    [du, dv] => Some((degree(du)?, Some(degree(dv)?))),
                    _ => {
                        return Err(Error::syntax(
                            "`deg` needs one degree (curves) or two (surfaces)",
                        ));
                    }
                };
            }
            "surf" => {
                if args.len() < 5 {
                    return Err(Error::syntax(
                        "`surf` needs s0 s1 t0 t1 and control vertices",
                    ));
                }
                let r = numbers(&args[..4])?;
                let kind = Kind::Surface {
                    range_u: Interval::new(r[0], r[1]),
                    range_v: Interval::new(r[2], r[3]),
                };
                self.begin(kind, &args[4..])?;
            }
            "curv" => {
                if args.len() < 3 {
                    return Err(Error::syntax("`curv` needs u0 u1 and control vertices"));
                }
                let r = numbers(&args[..2])?;
                self.begin(
                    Kind::Curve {
                        range: Interval::new(r[0], r[1]),
                    },
                    &args[2..],
                )?;
            }
            "curv2" => {
                if args.len() < 2 {
                    return Err(Error::syntax("`curv2` needs parameter vertices (`vp`)"));
                }
                self.begin(Kind::ParamCurve, args)?;
            }
            "g" => {
                // A group names the items that follow, until the next `g`.
                self.group = Some(if args.is_empty() {
                    "default".to_string()
                } else {
                    args.join(" ")
                });
            }
            "parm" | "trim" | "hole" | "scrv" | "sp" | "end" => {
                return Err(Error::syntax(format!(
                    "`{keyword}` outside a `surf`/`curv` element"
                )));
            }
            // Texture and normal vertices, polygons, groups, display and rendering attributes:
            // nothing knotwork tessellates.
            _ => {}
        }
        Ok(())
    }

    fn begin(&mut self, kind: Kind, references: &[&str]) -> Result<()> {
        let available = match kind {
            Kind::ParamCurve => self.param_vertices.len(),
            _ => self.vertices.len(),
        };
        let vertices = references
            .iter()
            .map(|r| resolve(r, available))
            .collect::<Result<Vec<_>>>()?;
        self.element = Some(Element {
            kind,
            line: self.line,
            cstype: self.cstype,
            degrees: self.degrees,
            vertices,
            parm_u: None,
            parm_v: None,
            loops: Vec::new(),
            special_curves: Vec::new(),
            special_points: Vec::new(),
        });
        Ok(())
    }

    fn body_statement(&mut self, keyword: &str, args: &[&str]) -> Result<()> {
        let line = self.line;
        let element = self.element.as_mut().expect("called inside an element");
        match keyword {
            "parm" => {
                let (direction, values) = args
                    .split_first()
                    .ok_or_else(|| Error::syntax("`parm` needs u|v and values"))?;
                let values = numbers(values)?;
                match *direction {
                    "u" => element.parm_u = Some((line, values)),
                    "v" => element.parm_v = Some((line, values)),
                    other => {
                        return Err(Error::syntax(format!(
                            "`parm {other}`: the direction must be u or v"
                        )));
                    }
                }
            }
            "trim" | "hole" | "scrv" | "sp" if !matches!(element.kind, Kind::Surface { .. }) => {
                return Err(Error::syntax(format!(
                    "`{keyword}` inside a `{}` element: trimming belongs to `surf`",
                    element.keyword()
                )));
            }
            "trim" | "hole" | "scrv" => {
                if args.is_empty() || !args.len().is_multiple_of(3) {
                    return Err(Error::syntax(format!(
                        "`{keyword}` needs triples u0 u1 curv2d, found {} values",
                        args.len()
                    )));
                }
                let pieces = args
                    .chunks_exact(3)
                    .map(|t| {
                        Ok((
                            number(t[0])?,
                            number(t[1])?,
                            resolve(t[2], self.param_curves.len())?,
                        ))
                    })
                    .collect::<Result<Vec<_>>>()?;
                let statement = LoopStatement {
                    hole: keyword == "hole",
                    line,
                    pieces,
                };
                if keyword == "scrv" {
                    element.special_curves.push(statement);
                } else {
                    element.loops.push(statement);
                }
            }
            "sp" => {
                for r in args {
                    let index = resolve(r, self.param_vertices.len())?;
                    element.special_points.push(index);
                }
            }
            "end" => {
                let element = self.element.take().expect("checked above");
                self.finish(element)?;
            }
            other => {
                return Err(Error::syntax(format!(
                    "`{other}` inside a `{}` element (missing `end`?)",
                    element.keyword()
                )));
            }
        }
        Ok(())
    }

    fn finish(&mut self, element: Element) -> Result<()> {
        let line = element.line;
        let keyword = element.keyword();
        let cstype = element.cstype.ok_or_else(|| {
            Error::syntax(format!("`{keyword}` before any `cstype`")).at_line(line)
        })?;
        let (du, dv) = element
            .degrees
            .ok_or_else(|| Error::syntax(format!("`{keyword}` before any `deg`")).at_line(line))?;
        let knots = |parm: Option<(usize, Vec<f64>)>,
                     degree: usize,
                     direction: &str|
         -> Result<KnotVector> {
            let (parm_line, values) = parm.ok_or_else(|| {
                Error::syntax(format!("`{keyword}` has no `parm {direction}`")).at_line(line)
            })?;
            let built = match cstype.basis {
                Basis::BSpline => KnotVector::try_new(degree, values),
                Basis::Bezier => KnotVector::from_breakpoints(degree, &values),
            };
            built.map_err(|e| e.at_line(parm_line))
        };
        let source = match element.kind {
            Kind::ParamCurve => &self.param_vertices,
            _ => &self.vertices,
        };
        let points: Vec<DVec3> = element.vertices.iter().map(|&i| source[i].0).collect();
        let weights: Option<Vec<f64>> = cstype
            .rational
            .then(|| element.vertices.iter().map(|&i| source[i].1).collect());
        match element.kind {
            Kind::Surface { range_u, range_v } => {
                let dv =
                    dv.ok_or_else(|| Error::syntax("a surface needs `deg du dv`").at_line(line))?;
                let ku = knots(element.parm_u, du, "u")?;
                let kv = knots(element.parm_v, dv, "v")?;
                let surface = BSplineSurface::try_new(ku, kv, &points, weights.as_deref())
                    .and_then(|s| s.with_range(range_u, range_v))
                    .map_err(|e| e.at_line(line))?;
                let special =
                    !element.special_curves.is_empty() || !element.special_points.is_empty();
                if element.loops.is_empty() && !special {
                    self.push(Geometry::Surface(surface));
                } else {
                    let face = (self.trimmed(surface, &element.loops))
                        .and_then(|face| {
                            self.with_special(
                                face,
                                &element.special_curves,
                                &element.special_points,
                            )
                        })
                        .map_err(|e| {
                            if e.line().is_some() {
                                e
                            } else {
                                e.at_line(line)
                            }
                        })?;
                    self.push(Geometry::Trimmed(Box::new(face)));
                }
            }
            Kind::Curve { range } => {
                let ku = knots(element.parm_u, du, "u")?;
                let curve = BSplineCurve::try_new(ku, &points, weights.as_deref())
                    .and_then(|c| c.with_range(range))
                    .map_err(|e| e.at_line(line))?;
                self.push(Geometry::Curve(curve));
            }
            Kind::ParamCurve => {
                let ku = knots(element.parm_u, du, "u")?;
                let curve = BSplineCurve::try_new(ku, &points, weights.as_deref())
                    .map_err(|e| e.at_line(line))?;
                self.param_curves.push(curve);
            }
        }
        Ok(())
    }

    /// The face `loops` cut from `surface`: the first `trim` loop is its outer loop (none:
    /// the surface's whole range), the other loops (holes, further `trim` loops) its further
    /// loops.
    fn trimmed(&self, surface: BSplineSurface, loops: &[LoopStatement]) -> Result<TrimmedSurface> {
        let mut outer = None;
        let mut others = Vec::new();
        for statement in loops {
            let trim_loop = TrimLoop {
                curves: self.pieces(statement)?,
            };
            if !statement.hole && outer.is_none() {
                outer = Some(trim_loop);
            } else {
                others.push(trim_loop);
            }
        }
        TrimmedSurface::try_new(surface, ParamMap::SAME, outer, others)
    }

    /// `face` with its element's special curves (`scrv`) and points (`sp`: `vp` indices).
    fn with_special(
        &self,
        face: TrimmedSurface,
        curves: &[LoopStatement],
        points: &[usize],
    ) -> Result<TrimmedSurface> {
        let curves = (curves.iter())
            .map(|statement| {
                Ok(SpecialCurve {
                    curves: self.pieces(statement)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let points: Vec<DVec2> = (points.iter())
            .map(|&k| self.param_vertices[k].0.truncate())
            .collect();
        face.with_special(curves, points)
    }

    /// The curves of a loop or special curve: each piece's `curv2` over [u0, u1], run
    /// backwards where u0 > u1. Errors name the statement's line.
    fn pieces(&self, statement: &LoopStatement) -> Result<Vec<BSplineCurve>> {
        (statement.pieces.iter())
            .map(|&(u0, u1, k)| {
                let curve = &self.param_curves[k];
                if u0 > u1 {
                    curve
                        .clone()
                        .with_range(Interval::new(u1, u0))
                        .map(|c| c.reversed())
                } else {
                    curve.clone().with_range(Interval::new(u0, u1))
                }
            })
            .collect::<Result<Vec<_>>>()
            .map_err(|e| e.at_line(statement.line))
    }
}
