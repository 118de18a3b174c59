//! Reader for the `.bpt` Bezier patch format of the Utah tea set.
//!
//! Layout: the patch count, then per patch its degrees `n m` and (n+1)·(m+1) points `x y z`,
//! listed with index i·(m+1) + j. knotwork reads j — the index that varies fastest — as the u
//! direction (degree m) and i as v (degree n), as OBJ does; this makes S_u × S_v point out of
//! the teapot.

use crate::error::{Error, Result};
use crate::geom::bezier_surface;
use crate::scene::{Geometry, Item, Scene};
use glam::DVec3;

/// Parses `.bpt` text. Errors carry the 1-based line ([`Error::AtLine`]).
pub fn read_bpt(text: &str) -> Result<Scene> {
    let mut tokens = Tokens {
        inner: text
            .lines()
            .enumerate()
            .flat_map(|(i, l)| l.split_whitespace().map(move |t| (i + 1, t))),
        line: 1,
    };
    let count: usize = tokens.parse("the patch count")?;
    let mut scene = Scene::default();
    // The count is untrusted: patches are read one by one, never preallocated from it.
    for patch in 0..count {
        let what = |s: &str| format!("{s} of patch {}", patch + 1);
        let n: usize = tokens.parse(&what("degree n"))?;
        let m: usize = tokens.parse(&what("degree m"))?;
        let line = tokens.line;
        crate::geom::check_degree(n)
            .and(crate::geom::check_degree(m))
            .map_err(|e| e.at_line(line))?;
        let mut points = Vec::with_capacity((n + 1) * (m + 1));
        for _ in 0..(n + 1) * (m + 1) {
            let mut xyz = [0.0; 3];
            for c in &mut xyz {
                *c = tokens.parse(&what("a coordinate"))?;
            }
            points.push(DVec3::from_array(xyz));
        }
        let surface = bezier_surface(m, n, &points, None).map_err(|e| e.at_line(line))?;
        scene.items.push(Item {
            name: Some("patches".into()),
            ..Item::new(Geometry::Surface(surface))
        });
    }
    if let Some((line, token)) = tokens.inner.next() {
        return Err(Error::syntax(format!(
            "unexpected `{token}` after the last of {count} patches"
        ))
        .at_line(line));
    }
    Ok(scene)
}

struct Tokens<I> {
    inner: I,
    /// Line of the last token read.
    line: usize,
}

impl<'a, I: Iterator<Item = (usize, &'a str)>> Tokens<I> {
    fn parse<T: std::str::FromStr>(&mut self, what: &str) -> Result<T> {
        let last = self.line;
        let (line, token) = self.inner.next().ok_or_else(|| {
            Error::UnexpectedEnd {
                expected: what.to_string(),
            }
            .at_line(last)
        })?;
        self.line = line;
        token
            .parse()
            .map_err(|_| Error::syntax(format!("expected {what}, found `{token}`")).at_line(line))
    }
}
