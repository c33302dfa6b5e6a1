//! Construction and incremental growth of an instance GraphSPN.

use std::collections::{BTreeMap, BTreeSet};

use thiserror::Error;

use crate::decompose::{Component, Decomposition, DecompositionStrategy};
use crate::inputs::{InputsError, check_inputs};
use crate::learn::Model;
use crate::map::TopoMap;
use crate::spn::{Node, NodeId, Spn};

/// How many decompositions an instance mixes, and how they are chosen.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InstanceParams {
    /// Number of decompositions D kept (the root sum's children). Default 5.
    pub decompositions: usize,
    /// Number of random candidate partitions by the largest template, of which the
    /// D with the best coverage are kept. Default 15.
    pub candidates: usize,
    /// Seed of every random choice.
    pub seed: u64,
    /// How candidate decompositions are drawn and ranked. Default: the paper's.
    pub strategy: DecompositionStrategy,
}

impl Default for InstanceParams {
    fn default() -> Self {
        InstanceParams {
            decompositions: 5,
            candidates: 15,
            seed: 0,
            strategy: DecompositionStrategy::Paper,
        }
    }
}

/// Why an instance could not be built.
#[derive(Debug, Error)]
pub enum InstanceError {
    /// The model, the map and the decompositions do not fit together.
    #[error(transparent)]
    Inputs(#[from] InputsError),
    /// [`Instance::update`] was given a map with fewer places than before.
    #[error("an instance can only grow: the map had {before} places and now has {after}")]
    MapShrank {
        /// Places before.
        before: usize,
        /// Places now.
        after: usize,
    },
}

/// An instance GraphSPN: the explicit SPN over all places of a map, and how it was assembled.
#[derive(Clone, Debug)]
pub struct Instance {
    /// The instance SPN; variable `p` is place `p` of the map.
    pub spn: Spn,
    /// The decompositions mixed by the root sum, in child order.
    pub decompositions: Vec<Decomposition>,
    /// Id of the leaf for (place, class): `leaves[p][c]`.
    leaves: Vec<Vec<NodeId>>,
    /// Root node of the template copy of each distinct component built so far.
    copies: BTreeMap<Component, NodeId>,
    /// Number of classes.
    num_classes: usize,
    /// Edges (place indices, smaller first) of the map the instance was last built for,
    /// so [`Instance::grow`] can tell which edges are new.
    pub(super) edges: BTreeSet<(usize, usize)>,
    /// Copies reused and built by the last [`Instance::build`] / [`Instance::update`].
    last_stats: CopyStats,
}

/// How many template copies an assembly reused from before and how many it built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CopyStats {
    /// Distinct components whose copy already existed and was kept as is.
    pub reused: usize,
    /// Distinct components whose copy was newly instantiated.
    pub built: usize,
}

impl Instance {
    /// Assembles the instance SPN of `map` from the given decompositions (Alg. 1).
    pub fn build(
        model: &Model,
        map: &TopoMap,
        decompositions: Vec<Decomposition>,
    ) -> Result<Instance, InstanceError> {
        check_inputs(model, map, &decompositions)?;
        let num_classes = model.classes.len();
        let mut instance = Instance {
            spn: Spn {
                classes: vec![num_classes as u32; map.num_places()],
                nodes: Vec::new(),
                root: 0,
            },
            decompositions: Vec::new(),
            leaves: Vec::new(),
            copies: BTreeMap::new(),
            num_classes,
            edges: edge_set(map),
            last_stats: CopyStats::default(),
        };
        instance.add_leaves(map.num_places());
        instance.assemble(model, decompositions);
        Ok(instance)
    }

    /// Replaces the decompositions after the map grew (places/edges added, existing place
    /// indices unchanged): template copies of components that are still used are kept as
    /// they are; only new components are instantiated, then the decomposition products and
    /// the root are rebuilt. Gives exactly the SPN [`Instance::build`] would give for the
    /// same decompositions, up to node order and unused copies being dropped.
    pub fn update(
        &mut self,
        model: &Model,
        map: &TopoMap,
        decompositions: Vec<Decomposition>,
    ) -> Result<(), InstanceError> {
        check_inputs(model, map, &decompositions)?;
        let old_places = self.leaves.len();
        if map.num_places() < old_places {
            return Err(InstanceError::MapShrank {
                before: old_places,
                after: map.num_places(),
            });
        }
        self.spn.classes = vec![self.num_classes as u32; map.num_places()];
        self.add_leaves(map.num_places() - old_places);
        // Drop the previous products and root, and copies no longer used, by compaction.
        let keep: std::collections::BTreeSet<&Component> = decompositions
            .iter()
            .flat_map(|d| d.components.iter())
            .collect();
        self.copies.retain(|c, _| keep.contains(c));
        self.compact();
        self.assemble(model, decompositions);
        self.edges = edge_set(map);
        Ok(())
    }

    /// Copies reused and built by the last [`Instance::build`] / [`Instance::update`]
    /// (a build reuses nothing; counts are of distinct components).
    pub fn last_copy_stats(&self) -> CopyStats {
        self.last_stats
    }

    /// Number of places (SPN variables) of the instance.
    pub fn num_places(&self) -> usize {
        self.leaves.len()
    }

    /// Number of classes per place.
    pub fn num_classes(&self) -> usize {
        self.num_classes
    }

    /// Number of template copies (distinct components) in the instance.
    pub fn num_copies(&self) -> usize {
        self.copies.len()
    }

    fn add_leaves(&mut self, count: usize) {
        let first_place = self.leaves.len();
        for p in first_place..first_place + count {
            let mut row = Vec::with_capacity(self.num_classes);
            for c in 0..self.num_classes {
                row.push(self.push(Node::Leaf {
                    var: p as u32,
                    class: c as u32,
                }));
            }
            self.leaves.push(row);
        }
    }

    fn push(&mut self, node: Node) -> NodeId {
        self.spn.nodes.push(node);
        (self.spn.nodes.len() - 1) as NodeId
    }

    /// Instantiates missing component copies, then the decomposition products and the root.
    fn assemble(&mut self, model: &Model, decompositions: Vec<Decomposition>) {
        let mut products = Vec::with_capacity(decompositions.len());
        let mut stats = CopyStats::default();
        let mut seen: BTreeSet<&Component> = BTreeSet::new();
        for d in &decompositions {
            let mut children = Vec::with_capacity(d.components.len());
            for comp in &d.components {
                let first_use = seen.insert(comp);
                let root = match self.copies.get(comp) {
                    Some(&r) => {
                        if first_use {
                            stats.reused += 1;
                        }
                        r
                    }
                    None => {
                        stats.built += 1;
                        let r = self.instantiate(&model.spns[comp.template], &comp.places);
                        self.copies.insert(comp.clone(), r);
                        r
                    }
                };
                children.push(root);
            }
            products.push(self.push(Node::Product { children }));
        }
        let w = 1.0 / products.len() as f64;
        let weights = vec![w; products.len()];
        self.spn.root = self.push(Node::Sum {
            children: products,
            weights,
        });
        self.decompositions = decompositions;
        self.last_stats = stats;
    }

    /// Copies a template SPN with its leaves bound to `places`; returns the copy's root.
    fn instantiate(&mut self, template: &Spn, places: &[usize]) -> NodeId {
        let mut map_ids: Vec<NodeId> = Vec::with_capacity(template.nodes.len());
        for node in &template.nodes {
            let id = match node {
                Node::Leaf { var, class } => self.leaves[places[*var as usize]][*class as usize],
                Node::Sum { children, weights } => {
                    let children = children.iter().map(|&c| map_ids[c as usize]).collect();
                    self.push(Node::Sum {
                        children,
                        weights: weights.clone(),
                    })
                }
                Node::Product { children } => {
                    let children = children.iter().map(|&c| map_ids[c as usize]).collect();
                    self.push(Node::Product { children })
                }
            };
            map_ids.push(id);
        }
        map_ids[template.root as usize]
    }

    /// Removes every node not reachable from a kept copy or a leaf, renumbering the rest
    /// in their current (topological) order. The root and products are dropped too.
    fn compact(&mut self) {
        let n = self.spn.nodes.len();
        let mut live = vec![false; n];
        for row in &self.leaves {
            for &l in row {
                live[l as usize] = true;
            }
        }
        for &r in self.copies.values() {
            live[r as usize] = true;
        }
        for i in (0..n).rev() {
            if !live[i] {
                continue;
            }
            match &self.spn.nodes[i] {
                Node::Leaf { .. } => {}
                Node::Sum { children, .. } | Node::Product { children } => {
                    for &c in children {
                        live[c as usize] = true;
                    }
                }
            }
        }
        let mut new_id = vec![NodeId::MAX; n];
        let mut nodes = Vec::with_capacity(n);
        for (i, node) in std::mem::take(&mut self.spn.nodes).into_iter().enumerate() {
            if !live[i] {
                continue;
            }
            new_id[i] = nodes.len() as NodeId;
            nodes.push(match node {
                Node::Leaf { .. } => node,
                Node::Sum { children, weights } => Node::Sum {
                    children: children.iter().map(|&c| new_id[c as usize]).collect(),
                    weights,
                },
                Node::Product { children } => Node::Product {
                    children: children.iter().map(|&c| new_id[c as usize]).collect(),
                },
            });
        }
        self.spn.nodes = nodes;
        for row in &mut self.leaves {
            for l in row.iter_mut() {
                *l = new_id[*l as usize];
            }
        }
        for r in self.copies.values_mut() {
            *r = new_id[*r as usize];
        }
    }
}

/// The edges of `map` as sorted (smaller, larger) place-index pairs.
pub(super) fn edge_set(map: &TopoMap) -> BTreeSet<(usize, usize)> {
    map.edge_list()
        .into_iter()
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect()
}
