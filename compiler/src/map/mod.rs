//! Topological maps: places joined by navigable edges.
//!
//! A [`TopoMap`] is an undirected petgraph graph without parallel edges or
//! self-loops. Node indices `0..n` are the *place order*: the variable order of
//! every SPN built for the map. Loaders keep places sorted by id.

use petgraph::graph::{NodeIndex, UnGraph};
use serde::{Deserialize, Serialize};

pub mod cold;
mod error;
mod graph;
mod json;
mod set;
pub mod stats;
pub mod synthetic;

pub use error::{MapError, MapFitError};
pub use json::MAP_FORMAT;
pub use set::{MapSetReport, load_map_set, load_map_set_report, map_set_name};

/// Index of a class in a [`ClassSet`].
pub type ClassId = u16;

/// User-facing id of a place (the COLD node id, or any id of a JSON map).
pub type PlaceId = u32;

/// The semantic classes a place can take, by name.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "stored::ClassSet")]
pub struct ClassSet {
    names: Vec<String>,
}

/// A [`ClassSet`] as files hold it, checked by [`ClassSet::new`] when read (its own
/// module, so serde's messages name it `ClassSet` too).
mod stored {
    /// The class names of a stored class set, unchecked.
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    pub(super) struct ClassSet {
        pub(super) names: Vec<String>,
    }
}

impl TryFrom<stored::ClassSet> for ClassSet {
    type Error = String;
    fn try_from(c: stored::ClassSet) -> Result<Self, String> {
        ClassSet::new(c.names)
    }
}

/// Class names for a message: all of them as a list when there are at most 12, else
/// the first 10 and how many there are (a message stays one readable line).
pub fn shown_class_names(names: &[String]) -> String {
    const ALL: usize = 12;
    const FIRST: usize = 10;
    if names.len() <= ALL {
        format!("{names:?}")
    } else {
        let first: Vec<String> = names[..FIRST].iter().map(|n| format!("{n:?}")).collect();
        format!("[{}, … ({} classes)]", first.join(", "), names.len())
    }
}

/// The paper's ten classes, in index order (listed with their COLD labels in `docs/FORMATS.md`).
pub const PAPER_CLASSES: [&str; 10] = [
    "DW", "CR", "1PO", "2PO", "LO", "LAB", "BA", "KT", "MR", "UT",
];

impl ClassSet {
    /// A class set from names: at least one, at most 65,536 (a [`ClassId`] is 16-bit),
    /// all distinct.
    pub fn new(names: Vec<String>) -> Result<Self, String> {
        if names.is_empty() {
            return Err("a class set needs at least one class".into());
        }
        if names.len() > usize::from(ClassId::MAX) + 1 {
            return Err(format!(
                "{} classes: at most {} (class indices are 16-bit)",
                names.len(),
                usize::from(ClassId::MAX) + 1
            ));
        }
        let mut seen = std::collections::HashSet::new();
        for n in &names {
            if !seen.insert(n.as_str()) {
                return Err(format!("class name {n:?} appears twice"));
            }
        }
        Ok(ClassSet { names })
    }

    /// The paper's ten classes ([`PAPER_CLASSES`]).
    pub fn paper() -> Self {
        ClassSet {
            names: PAPER_CLASSES.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// Number of classes.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Always false: a class set has at least one class.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Class names in index order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Name of class `c`.
    pub fn name(&self, c: ClassId) -> &str {
        &self.names[c as usize]
    }

    /// Index of the class called `name`.
    pub fn index_of(&self, name: &str) -> Option<ClassId> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| i as ClassId)
    }
}

/// A place of a topological map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Place {
    /// User-facing id, unique within the map.
    pub id: PlaceId,
    /// Ground-truth class, when annotated.
    pub class: Option<ClassId>,
    /// A frontier the robot has not visited yet (no local evidence).
    pub placeholder: bool,
    /// Pose x in metres (for drawing).
    pub x: f64,
    /// Pose y in metres (for drawing).
    pub y: f64,
}

/// A topological map: places (nodes) joined by undirected navigable edges.
#[derive(Clone, Debug)]
pub struct TopoMap {
    /// Human-readable name, e.g. `Freiburg/seq1_cloudy1`.
    pub name: String,
    /// The classes places may take.
    pub classes: ClassSet,
    /// The graph; node weights are places, in place order.
    pub graph: UnGraph<Place, ()>,
}

impl TopoMap {
    /// Whether a model of `classes` can label this map: the same class names in the
    /// same order, at least one place, and a graph that keeps the map's invariants
    /// (which its public fields let a caller break after [`TopoMap::new`]: ids
    /// strictly increasing in place order, class indices within the classes, no
    /// self-loop, no repeated edge). Every model family's input check runs it.
    pub fn check_labellable(&self, classes: &ClassSet) -> Result<(), MapFitError> {
        if self.classes != *classes {
            return Err(MapFitError::ClassMismatch {
                map: self.name.clone(),
                map_classes: self.classes.names().to_vec(),
                model_classes: classes.names().to_vec(),
            });
        }
        if self.num_places() == 0 {
            return Err(MapFitError::Empty(self.name.clone()));
        }
        self.check_graph().map_err(|what| MapFitError::Malformed {
            map: self.name.clone(),
            what,
        })
    }

    /// The graph's invariants ([`TopoMap::check_labellable`]), or what breaks first.
    fn check_graph(&self) -> Result<(), String> {
        let places: Vec<&Place> = self.places().collect();
        for (i, pair) in places.windows(2).enumerate() {
            if pair[0].id >= pair[1].id {
                return Err(format!(
                    "place ids are not strictly increasing in place order: id {} at index {} \
                     is followed by id {}",
                    pair[0].id, i, pair[1].id
                ));
            }
        }
        if let Some((i, p)) = places.iter().enumerate().find(|(_, p)| {
            p.class
                .is_some_and(|c| usize::from(c) >= self.classes.len())
        }) {
            return Err(format!(
                "place {} (index {i}) has class index {} of {} classes",
                p.id,
                p.class.unwrap_or_default(),
                self.classes.len()
            ));
        }
        let edges = self.edge_list();
        if let Some(&(a, _)) = edges.iter().find(|(a, b)| a == b) {
            return Err(format!("place {} has an edge to itself", places[a].id));
        }
        if let Some(w) = edges.windows(2).find(|w| w[0] == w[1]) {
            return Err(format!(
                "the edge between places {} and {} is there twice",
                places[w[0].0].id, places[w[0].1].id
            ));
        }
        Ok(())
    }

    /// Number of places.
    pub fn num_places(&self) -> usize {
        self.graph.node_count()
    }

    /// Number of undirected edges.
    pub fn num_edges(&self) -> usize {
        self.graph.edge_count()
    }

    /// The place at index `i` of the place order.
    pub fn place(&self, i: usize) -> &Place {
        &self.graph[NodeIndex::new(i)]
    }

    /// All places in place order.
    pub fn places(&self) -> impl Iterator<Item = &Place> {
        self.graph.node_weights()
    }

    /// Indices of the neighbours of place `i`, ascending.
    pub fn neighbors(&self, i: usize) -> Vec<usize> {
        let mut v: Vec<usize> = self
            .graph
            .neighbors(NodeIndex::new(i))
            .map(|n| n.index())
            .collect();
        v.sort_unstable();
        v
    }
}
