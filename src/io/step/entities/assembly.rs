//! The scene of a STEP file: its solids, placed by the assembly structure and named after
//! their products and instances.
//!
//! A product's shape is a representation holding solids; an assembly's representation has
//! parts placed in it, each a `REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION` (named by
//! the `NEXT_ASSEMBLY_USAGE_OCCURRENCE` its `CONTEXT_DEPENDENT_SHAPE_REPRESENTATION` points
//! at) or a `MAPPED_ITEM`. A relationship without a transformation says two representations
//! are one (a product's `SHAPE_REPRESENTATION` and the B-rep representation beside it), so
//! representations are merged into classes along those first.

use super::{MAX_DEPTH, Model, Rec, problem};
use crate::error::{Error, Result};
use crate::geom::brep::Shell;
use crate::io::step::file::Value;
use crate::scene::{Dropped, Geometry, Item, Scene, SceneNode};
use glam::DMat4;
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// Most nodes an assembly may expand to (every instance of every part, sub-assemblies
/// included): the tree is built before any solid is placed, so a file cannot make the reader
/// allocate more.
const MAX_NODES: usize = 1 << 16;

/// A part placed in an assembly: the placed class, where, and the instance's name where the
/// file gives one.
struct Placement {
    child: u64,
    /// From the part's coordinates to the assembly's.
    transform: DMat4,
    name: Option<String>,
}

/// The assembly structure of a file, over classes of representations (a class is named by
/// its smallest representation id).
#[derive(Default)]
struct Assembly {
    /// Representation → another of its class, up to the class's representative.
    merged: HashMap<u64, u64>,
    /// Class → the parts placed in it, in file order.
    parts: BTreeMap<u64, Vec<Placement>>,
    /// Class → the solids and shells among its items, in file order.
    solids: BTreeMap<u64, Vec<u64>>,
    /// Class → its product's name.
    names: HashMap<u64, String>,
    /// Class → the name of its first representation, for a class without a product.
    fallback_names: HashMap<u64, String>,
}

impl Assembly {
    fn class(&self, mut rep: u64) -> u64 {
        while let Some(&next) = self.merged.get(&rep) {
            rep = next;
        }
        rep
    }

    fn merge(&mut self, a: u64, b: u64) {
        let (a, b) = (self.class(a), self.class(b));
        if a != b {
            self.merged.insert(a.max(b), a.min(b));
        }
    }
}

/// One node of the expanded tree, before its solids are placed.
struct Expanded {
    node: SceneNode,
    /// The solid it shows, if any.
    solid: Option<u64>,
    /// Its names from the root down, joined by "/": the name of the items it shows.
    path: String,
}

impl Model<'_> {
    /// The scene: every solid and surface model (each shell one item), placed by the
    /// assembly structure — one placed copy per instance, and the placement tree in
    /// [`Scene::nodes`] where the file has an assembly — and named after its instance path,
    /// product or own name.
    pub fn scene(&self) -> Result<Scene> {
        let mut scene = Scene::default();
        let mut ids: Vec<u64> = self.file.instances.keys().copied().collect();
        ids.sort_unstable();
        // Every solid, surface model and free shell, with its shells.
        let mut solids: BTreeMap<u64, Vec<u64>> = BTreeMap::new();
        for &id in &ids {
            let record = &self.file.instances[&id].records[0];
            let rec = Rec { id, record };
            let shells = match record.name.as_str() {
                "MANIFOLD_SOLID_BREP" => vec![rec.reference(1)?],
                "BREP_WITH_VOIDS" => {
                    let mut s = vec![rec.reference(1)?];
                    s.extend(rec.references(2)?);
                    s
                }
                "SHELL_BASED_SURFACE_MODEL" => rec.references(1)?,
                _ => continue,
            };
            solids.insert(id, shells);
        }
        let used_shells: BTreeSet<u64> = solids.values().flatten().copied().collect();
        for &id in &ids {
            let record = &self.file.instances[&id].records[0];
            if matches!(record.name.as_str(), "CLOSED_SHELL" | "OPEN_SHELL")
                && !used_shells.contains(&id)
            {
                solids.insert(id, vec![id]);
            }
        }
        let solid_ids: BTreeSet<u64> = solids.keys().copied().collect();
        let assembly = self.assembly(&ids, &solid_ids)?;
        let tree = self.expand(&assembly)?;
        let has_parts = assembly.parts.values().any(|parts| !parts.is_empty());
        scene.nodes = tree.iter().map(|e| e.node.clone()).collect();
        let placements = scene.node_placements()?;
        let mut read: HashMap<u64, Vec<Shell>> = HashMap::new();
        let mut shown_by: HashMap<u64, usize> = HashMap::new();
        let mut placed = BTreeSet::new();
        for (k, e) in tree.iter().enumerate() {
            let Some(solid) = e.solid else { continue };
            placed.insert(solid);
            let shells = read.entry(solid).or_insert_with(|| {
                self.solid_shells(solid, &solids[&solid], &e.path, &mut scene.dropped)
            });
            let first = scene.items.len();
            for shell in shells.iter() {
                let placement = placements[k];
                let shell = if placement == DMat4::IDENTITY {
                    shell.clone()
                } else {
                    shell.mapped(|p| placement.transform_point3(p))
                };
                let mut item = Item::new(Geometry::Shell(Box::new(shell)));
                item.name = Some(e.path.clone());
                scene.items.push(item);
            }
            let node = &mut scene.nodes[k];
            node.items = first..scene.items.len();
            if !node.items.is_empty() {
                node.copy_of = shown_by.get(&solid).copied();
                shown_by.entry(solid).or_insert(k);
            }
        }
        // Solids in no representation: at the origin, under their own names.
        for (&solid, shells) in &solids {
            if placed.contains(&solid) {
                continue;
            }
            let name = self.own_name(solid);
            for shell in self.solid_shells(solid, shells, &name, &mut scene.dropped) {
                let mut item = Item::new(Geometry::Shell(Box::new(shell)));
                item.name = Some(name.clone());
                scene.items.push(item);
            }
        }
        if !has_parts {
            // No assembly: the names are all there is to keep of the tree.
            scene.nodes.clear();
        }
        if self.length_scale != 1.0 {
            scene.notes.push(format!(
                "lengths converted to millimetres (× {})",
                self.length_scale
            ));
        }
        if scene.items.is_empty() && scene.dropped.is_empty() {
            // As IGES files with no surface: an empty mesh would pass for a meshed part.
            return Err(Error::syntax(format!(
                "no B-rep in the file (knotwork meshes MANIFOLD_SOLID_BREP, BREP_WITH_VOIDS, SHELL_BASED_SURFACE_MODEL and free CLOSED_SHELL/OPEN_SHELL; it holds {} instances of other kinds)",
                self.file.instances.len()
            )));
        }
        Ok(scene)
    }

    /// The `shells` of `solid` (a solid, surface model or free shell) that can be read; the
    /// others listed in `dropped` under `name`, with why.
    fn solid_shells(
        &self,
        solid: u64,
        shells: &[u64],
        name: &str,
        dropped: &mut Vec<Dropped>,
    ) -> Vec<Shell> {
        let mut read = Vec::new();
        for &shell in shells {
            match self.shell(shell, dropped) {
                Ok(s) => read.push(s),
                Err(error) => dropped.push(Dropped {
                    what: format!("{name} (#{solid})"),
                    reason: error.to_string(),
                }),
            }
        }
        read
    }

    /// A solid's name: its own (the first parameter), else its entity's kind and id.
    fn own_name(&self, solid: u64) -> String {
        let record = &self.file.instances[&solid].records[0];
        self.text(solid, 0)
            .unwrap_or_else(|| format!("{} #{solid}", record.name))
    }

    /// The non-blank text parameter `k` of `id`'s first record.
    fn text(&self, id: u64, k: usize) -> Option<String> {
        let record = self.file.instances.get(&id)?.records.first()?;
        match record.params.get(k) {
            Some(Value::Text(t)) if !t.trim().is_empty() => Some(t.trim().to_string()),
            _ => None,
        }
    }

    /// The name of the product whose definition `definition_shape` (a
    /// PRODUCT_DEFINITION_SHAPE) describes: the product's name, else its id; `None` where
    /// the chain PRODUCT_DEFINITION → formation → PRODUCT is broken (names are optional).
    fn product_name(&self, definition_shape: u64) -> Option<String> {
        let definition = self.reference_at(definition_shape, 2)?;
        let formation = self.reference_at(definition, 2)?;
        let product = self.reference_at(formation, 2)?;
        self.text(product, 1).or_else(|| self.text(product, 0))
    }

    /// The reference in parameter `k` of `id`'s first record, if it is one (for names,
    /// which are optional: nothing there is an error).
    fn reference_at(&self, id: u64, k: usize) -> Option<u64> {
        match self.file.instances.get(&id)?.records.first()?.params.get(k) {
            Some(Value::Ref(r)) => Some(*r),
            _ => None,
        }
    }

    /// The name of the instance a CONTEXT_DEPENDENT_SHAPE_REPRESENTATION's
    /// PRODUCT_DEFINITION_SHAPE (`definition_shape`) stands for: the assembly usage's name,
    /// else its id.
    fn usage_name(&self, definition_shape: u64) -> Option<String> {
        let usage = self.reference_at(definition_shape, 2)?;
        self.text(usage, 1).or_else(|| self.text(usage, 0))
    }

    /// Reads the assembly structure: which representations are one, which parts each class
    /// places where, which of `solids` each holds, and the names of products and instances.
    fn assembly(&self, ids: &[u64], solids: &BTreeSet<u64>) -> Result<Assembly> {
        let mut assembly = Assembly::default();
        // (child representation, parent representation, transform, relationship id)
        let mut placed: Vec<(u64, u64, DMat4, Option<u64>)> = Vec::new();
        let mut usage_of_relationship: HashMap<u64, String> = HashMap::new();
        let mut product_of_rep: Vec<(u64, String)> = Vec::new();
        let mut items_of_rep: Vec<(u64, Vec<u64>)> = Vec::new();
        for &id in ids {
            let instance = &self.file.instances[&id];
            if let Some(r) = instance.record("REPRESENTATION_RELATIONSHIP") {
                let rec = Rec { id, record: r };
                let (rep1, rep2) = (rec.reference(2)?, rec.reference(3)?);
                match instance.record("REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION") {
                    Some(t) => {
                        let t = Rec { id, record: t };
                        let idt = self.expect(t.reference(0)?, &["ITEM_DEFINED_TRANSFORMATION"])?;
                        let from = self.frame(idt.reference(2)?)?;
                        let to = self.frame(idt.reference(3)?)?;
                        // rep1 is placed in rep2: its item `from` lands on rep2's `to`.
                        let transform = to.matrix() * from.matrix().inverse();
                        placed.push((rep1, rep2, transform, Some(id)));
                    }
                    None => assembly.merge(rep1, rep2),
                }
            }
            let record = &instance.records[0];
            let rec = Rec { id, record };
            match record.name.as_str() {
                // The simple form of an untransformed relationship (a product's shape and
                // its B-rep's representation).
                "SHAPE_REPRESENTATION_RELATIONSHIP" => {
                    if let (Ok(rep1), Ok(rep2)) = (rec.reference(2), rec.reference(3)) {
                        assembly.merge(rep1, rep2);
                    }
                }
                "CONTEXT_DEPENDENT_SHAPE_REPRESENTATION" => {
                    if let (Ok(relationship), Ok(shape)) = (rec.reference(0), rec.reference(1))
                        && let Some(name) = self.usage_name(shape)
                    {
                        usage_of_relationship.insert(relationship, name);
                    }
                }
                "SHAPE_DEFINITION_REPRESENTATION" => {
                    if let (Ok(shape), Ok(rep)) = (rec.reference(0), rec.reference(1))
                        && let Some(name) = self.product_name(shape)
                    {
                        product_of_rep.push((rep, name));
                    }
                }
                "MAPPED_ITEM" => {
                    let map = self.expect(rec.reference(1)?, &["REPRESENTATION_MAP"])?;
                    let origin = self.frame(map.reference(0)?)?;
                    let target = self.frame(rec.reference(2)?)?;
                    let transform = target.matrix() * origin.matrix().inverse();
                    // The representation holding the item is found below, from its items.
                    placed.push((map.reference(1)?, id, transform, None));
                }
                name if name.ends_with("REPRESENTATION") && record.params.len() >= 2 => {
                    if let Ok(items) = rec.references(1) {
                        if let Some(name) = self.text(id, 0) {
                            assembly.fallback_names.insert(id, name);
                        }
                        items_of_rep.push((id, items));
                    }
                }
                _ => {}
            }
        }
        // A mapped item places its representation in the representation holding the item.
        let mut holder_of_mapped_item: HashMap<u64, u64> = HashMap::new();
        for (rep, items) in &items_of_rep {
            for &item in items {
                if solids.contains(&item) {
                    assembly
                        .solids
                        .entry(assembly.class(*rep))
                        .or_default()
                        .push(item);
                } else {
                    holder_of_mapped_item.insert(item, *rep);
                }
            }
        }
        for (child, parent, transform, relationship) in placed {
            let (parent, name) = match relationship {
                Some(r) => (parent, usage_of_relationship.get(&r).cloned()),
                None => match holder_of_mapped_item.get(&parent) {
                    Some(&holder) => (holder, self.text(parent, 0)),
                    // A mapped item no representation holds places nothing.
                    None => continue,
                },
            };
            let (child, parent) = (assembly.class(child), assembly.class(parent));
            if child == parent {
                return Err(problem(
                    relationship.unwrap_or(parent),
                    "REPRESENTATION_RELATIONSHIP",
                    "places a representation in itself",
                ));
            }
            assembly.parts.entry(parent).or_default().push(Placement {
                child,
                transform,
                name,
            });
        }
        for (rep, name) in product_of_rep {
            let class = assembly.class(rep);
            assembly.names.entry(class).or_insert(name);
        }
        // Each class keeps the name of its smallest named representation.
        let mut named: Vec<(u64, String)> = assembly.fallback_names.drain().collect();
        named.sort_unstable_by_key(|&(rep, _)| std::cmp::Reverse(rep));
        for (rep, name) in named {
            let class = assembly.class(rep);
            assembly.fallback_names.insert(class, name);
        }
        Ok(assembly)
    }

    /// A class's name: its product's, else its representation's, else (holding one solid)
    /// the solid's, else its representation's kind and id.
    fn class_name(&self, assembly: &Assembly, class: u64) -> String {
        if let Some(name) = assembly.names.get(&class) {
            return name.clone();
        }
        if let Some(name) = assembly.fallback_names.get(&class) {
            return name.clone();
        }
        match assembly.solids.get(&class).map(Vec::as_slice) {
            Some(&[solid]) => self.own_name(solid),
            _ => {
                let kind = self.file.instances.get(&class).map(|i| i.kind());
                format!("{} #{class}", kind.unwrap_or_default())
            }
        }
    }

    /// The placement tree: from each class placed in no other (with solids or parts), a
    /// node per instance of every part, down to nodes showing one solid each; siblings of
    /// one name told apart by " [k]". Each node comes after its parent.
    fn expand(&self, assembly: &Assembly) -> Result<Vec<Expanded>> {
        let children: BTreeSet<u64> = (assembly.parts.values().flatten())
            .map(|p| p.child)
            .collect();
        let mut roots: BTreeSet<u64> = (assembly.solids.keys().chain(assembly.parts.keys()))
            .copied()
            .filter(|class| !children.contains(class))
            .collect();
        // A representation that only lists solids an earlier root holds too (unlinked to
        // it by any relationship) shows them again in the same place: not a second copy.
        let mut held = BTreeSet::new();
        roots.retain(|class| {
            let solids = assembly.solids.get(class).map_or(&[][..], Vec::as_slice);
            let again = assembly.parts.get(class).is_none_or(Vec::is_empty)
                && solids.iter().all(|s| held.contains(s));
            held.extend(solids.iter().copied());
            !again
        });
        let mut tree: Vec<Expanded> = Vec::new();
        // (class, name, transform, parent node, depth)
        let mut stack: Vec<(u64, String, DMat4, Option<usize>, usize)> = roots
            .iter()
            .rev()
            .map(|&class| {
                (
                    class,
                    self.class_name(assembly, class),
                    DMat4::IDENTITY,
                    None,
                    0,
                )
            })
            .collect();
        while let Some((class, name, transform, parent, depth)) = stack.pop() {
            if depth > MAX_DEPTH {
                return Err(problem(
                    class,
                    "REPRESENTATION_RELATIONSHIP",
                    "assemblies nest too deeply (a cycle?)",
                ));
            }
            if tree.len() >= MAX_NODES {
                return Err(problem(
                    class,
                    "assembly",
                    format!("expands to more than {MAX_NODES} instances"),
                ));
            }
            let path = match parent {
                Some(p) => format!("{}/{name}", tree[p].path),
                None => name.clone(),
            };
            let solids = assembly.solids.get(&class).map_or(&[][..], Vec::as_slice);
            let parts = assembly.parts.get(&class).map_or(&[][..], Vec::as_slice);
            let here = tree.len();
            let shows_its_solid = solids.len() == 1 && parts.is_empty();
            tree.push(Expanded {
                node: SceneNode {
                    name,
                    parent,
                    transform,
                    items: 0..0,
                    copy_of: None,
                    shape: shows_its_solid.then(|| self.class_name(assembly, class)),
                },
                solid: shows_its_solid.then(|| solids[0]),
                path,
            });
            if shows_its_solid {
                continue;
            }
            let mut names: Vec<String> = solids.iter().map(|&s| self.own_name(s)).collect();
            names.extend(parts.iter().map(|p| {
                p.name
                    .clone()
                    .unwrap_or_else(|| self.class_name(assembly, p.child))
            }));
            let names = distinct(names);
            for (&solid, name) in solids.iter().zip(&names) {
                let path = format!("{}/{name}", tree[here].path);
                tree.push(Expanded {
                    node: SceneNode {
                        name: name.clone(),
                        parent: Some(here),
                        transform: DMat4::IDENTITY,
                        items: 0..0,
                        copy_of: None,
                        shape: None,
                    },
                    solid: Some(solid),
                    path,
                });
            }
            // Reversed onto the stack: parts come out in file order.
            for (part, name) in parts.iter().zip(&names[solids.len()..]).rev() {
                stack.push((
                    part.child,
                    name.clone(),
                    part.transform,
                    Some(here),
                    depth + 1,
                ));
            }
        }
        Ok(tree)
    }
}

/// `names` with each name that occurs more than once suffixed " [k]" (k counting its
/// occurrences from 1).
fn distinct(names: Vec<String>) -> Vec<String> {
    let mut total: HashMap<&str, usize> = HashMap::new();
    for name in &names {
        *total.entry(name).or_default() += 1;
    }
    let mut seen: HashMap<&str, usize> = HashMap::new();
    names
        .iter()
        .map(|name| {
            if total[name.as_str()] == 1 {
                return name.clone();
            }
            let k = seen.entry(name).or_default();
            *k += 1;
            format!("{name} [{k}]")
        })
        .collect()
}
