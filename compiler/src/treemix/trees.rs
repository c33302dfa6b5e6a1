//! Edge-covering spanning trees of a map, rooted at their centres.
//!
//! [`SpanningTrees::covering`] draws `T` spanning forests (one tree per connected
//! component) by Kruskal's algorithm over the map's edges ordered by how many
//! earlier forests used them (fewest first), ties broken by a seeded random key: the
//! first forest is a random spanning forest, each next one takes as many edges no
//! forest has used yet as a forest can hold. On the COLD maps (about 1.9 edges per
//! place) two or three forests cover every edge. Each tree is rooted at its centre (a
//! middle place of a longest path, the smaller index of two), which minimises its
//! height: the depth bounds the scratch memory of the generated code's passes and the
//! cost of a streaming update.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{TreeMixError, TreeMixture};
use crate::map::TopoMap;

/// Parent of a root in [`RootedForest::parent`].
pub const NO_PARENT: u32 = u32::MAX;

/// One spanning forest of a map, rooted: a tree per connected component.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RootedForest {
    /// Parent of every place (place order), [`NO_PARENT`] for a root.
    pub parent: Vec<u32>,
    /// Every place in breadth-first order from the roots: parents before their
    /// children, children of one place in increasing place order, roots in
    /// increasing place order.
    pub order: Vec<u32>,
    /// Depth of every place (roots: 0).
    pub depth: Vec<u32>,
}

impl RootedForest {
    /// A forest from undirected `edges` over `n` places (must be acyclic): each
    /// component rooted at its centre.
    pub fn from_edges(n: usize, edges: &[(u32, u32)]) -> Result<Self, TreeMixError> {
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); n];
        for &(a, b) in edges {
            if a as usize >= n || b as usize >= n || a == b {
                return Err(TreeMixError::BadTrees(format!(
                    "edge ({a}, {b}) is not an edge between two of the {n} places"
                )));
            }
            adj[a as usize].push(b);
            adj[b as usize].push(a);
        }
        for a in &mut adj {
            a.sort_unstable();
        }
        let mut parent = vec![NO_PARENT; n];
        let mut depth = vec![0u32; n];
        let mut order = Vec::with_capacity(n);
        let mut seen = vec![false; n];
        let mut scratch = Scratch::new(n);
        for start in 0..n as u32 {
            if seen[start as usize] {
                continue;
            }
            let root = scratch.centre(&adj, start);
            // Breadth-first from the root.
            let mut i = order.len();
            order.push(root);
            seen[root as usize] = true;
            while i < order.len() {
                let v = order[i];
                i += 1;
                for &w in &adj[v as usize] {
                    if !seen[w as usize] {
                        seen[w as usize] = true;
                        parent[w as usize] = v;
                        depth[w as usize] = depth[v as usize] + 1;
                        order.push(w);
                    }
                }
            }
        }
        let forest = RootedForest {
            parent,
            order,
            depth,
        };
        if forest.edges().len() != edges.len() {
            return Err(TreeMixError::BadTrees(format!(
                "the {} edges given hold a cycle or a repeated edge",
                edges.len()
            )));
        }
        Ok(forest)
    }

    /// Number of places.
    pub fn num_places(&self) -> usize {
        self.parent.len()
    }

    /// The forest's edges as `(parent, child)` in breadth-first order of the child.
    pub fn edges(&self) -> Vec<(u32, u32)> {
        self.order
            .iter()
            .filter(|&&v| self.parent[v as usize] != NO_PARENT)
            .map(|&v| (self.parent[v as usize], v))
            .collect()
    }

    /// The roots, in increasing place order.
    pub fn roots(&self) -> Vec<u32> {
        self.order
            .iter()
            .copied()
            .filter(|&v| self.parent[v as usize] == NO_PARENT)
            .collect()
    }

    /// Children of every place, each list in increasing place order.
    pub fn children(&self) -> Vec<Vec<u32>> {
        let mut ch = vec![Vec::new(); self.num_places()];
        for &v in &self.order {
            let p = self.parent[v as usize];
            if p != NO_PARENT {
                ch[p as usize].push(v);
            }
        }
        ch
    }

    /// Largest depth of a place (0 for a forest of single places).
    pub fn height(&self) -> u32 {
        self.depth.iter().copied().max().unwrap_or(0)
    }
}

/// Reusable buffers of the centre search (each search resets what it touched).
struct Scratch {
    dist: Vec<u32>,
    parent: Vec<u32>,
    order: Vec<u32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Scratch {
            dist: vec![u32::MAX; n],
            parent: vec![NO_PARENT; n],
            order: Vec::new(),
        }
    }

    /// Breadth-first search from `start`: fills `order`, `dist`, `parent`; returns
    /// the farthest place (the smallest index among ties).
    fn search(&mut self, adj: &[Vec<u32>], start: u32) -> u32 {
        for &v in &self.order {
            self.dist[v as usize] = u32::MAX;
            self.parent[v as usize] = NO_PARENT;
        }
        self.order.clear();
        self.order.push(start);
        self.dist[start as usize] = 0;
        let mut best = (0, start);
        let mut i = 0;
        while i < self.order.len() {
            let v = self.order[i];
            i += 1;
            let d = self.dist[v as usize];
            if d > best.0 || (d == best.0 && v < best.1) {
                best = (d, v);
            }
            for &w in &adj[v as usize] {
                if self.dist[w as usize] == u32::MAX {
                    self.dist[w as usize] = d + 1;
                    self.parent[w as usize] = v;
                    self.order.push(w);
                }
            }
        }
        best.1
    }

    /// The centre of the tree holding `start`: the middle place of a longest path
    /// (the smaller index of the two middle places when its length is odd).
    fn centre(&mut self, adj: &[Vec<u32>], start: u32) -> u32 {
        self.search(adj, start);
        let first = *self.order.iter().min().expect("a component has a place");
        let u = self.search(adj, first);
        let v = self.search(adj, u);
        let mut path = vec![v];
        while *path.last().expect("non-empty") != u {
            path.push(self.parent[*path.last().expect("non-empty") as usize]);
        }
        let len = path.len();
        if len % 2 == 1 {
            path[len / 2]
        } else {
            path[len / 2 - 1].min(path[len / 2])
        }
    }
}

/// The spanning forests a tree mixture of one map mixes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SpanningTrees {
    /// The forests, in mixture order.
    pub forests: Vec<RootedForest>,
}

impl SpanningTrees {
    /// `count` edge-covering spanning forests of `map`, seeded (see the module docs).
    /// Deterministic: the same map, count and seed give the same forests.
    pub fn covering(map: &TopoMap, count: usize, seed: u64) -> Result<Self, TreeMixError> {
        let n = map.num_places();
        if n == 0 {
            return Err(crate::map::MapFitError::Empty(map.name.clone()).into());
        }
        if count == 0 {
            return Err(TreeMixError::BadTrees(
                "a tree mixture needs at least one tree".into(),
            ));
        }
        let edges: Vec<(u32, u32)> = map
            .edge_list()
            .into_iter()
            .map(|(a, b)| (a as u32, b as u32))
            .collect();
        let mut used = vec![0u32; edges.len()];
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut forests = Vec::with_capacity(count);
        for _ in 0..count {
            let mut keyed: Vec<(u32, u64, usize)> = (0..edges.len())
                .map(|e| (used[e], rng.random::<u64>(), e))
                .collect();
            keyed.sort_unstable();
            let mut sets: Vec<u32> = (0..n as u32).collect();
            let mut chosen = Vec::with_capacity(n.saturating_sub(1));
            for &(_, _, e) in &keyed {
                let (a, b) = edges[e];
                let (ra, rb) = (find(&mut sets, a), find(&mut sets, b));
                if ra != rb {
                    sets[ra as usize] = rb;
                    chosen.push((a, b));
                    used[e] += 1;
                }
            }
            chosen.sort_unstable();
            forests.push(RootedForest::from_edges(n, &chosen)?);
        }
        Ok(SpanningTrees { forests })
    }

    /// Number of forests (trees of the mixture).
    pub fn len(&self) -> usize {
        self.forests.len()
    }

    /// Whether there is no forest.
    pub fn is_empty(&self) -> bool {
        self.forests.is_empty()
    }

    /// `(edges of map covered by some forest, edges of map)`.
    pub fn coverage(&self, map: &TopoMap) -> (usize, usize) {
        let all = map.edge_list();
        let mut covered = std::collections::BTreeSet::new();
        for f in &self.forests {
            for (p, c) in f.edges() {
                covered.insert((p.min(c) as usize, p.max(c) as usize));
            }
        }
        (
            all.iter().filter(|e| covered.contains(e)).count(),
            all.len(),
        )
    }

    /// Checks that every forest spans exactly the places of `map` with edges of `map`.
    pub fn check_fits(&self, map: &TopoMap) -> Result<(), TreeMixError> {
        let n = map.num_places();
        for (t, f) in self.forests.iter().enumerate() {
            if f.num_places() != n || f.order.len() != n || f.depth.len() != n {
                return Err(TreeMixError::BadTrees(format!(
                    "tree {t} has {} places, the map {:?} has {n}",
                    f.num_places(),
                    map.name
                )));
            }
            for (p, c) in f.edges() {
                if !map.has_edge(p as usize, c as usize) {
                    return Err(TreeMixError::BadTrees(format!(
                        "tree {t}: ({p}, {c}) is not an edge of the map {:?}",
                        map.name
                    )));
                }
            }
            let components = map.connected_components().len();
            if f.roots().len() != components {
                return Err(TreeMixError::BadTrees(format!(
                    "tree {t} has {} roots, the map {:?} has {components} connected components",
                    f.roots().len(),
                    map.name
                )));
            }
        }
        Ok(())
    }
}

fn find(sets: &mut [u32], x: u32) -> u32 {
    let mut r = x;
    while sets[r as usize] != r {
        r = sets[r as usize];
    }
    let mut y = x;
    while sets[y as usize] != r {
        let next = sets[y as usize];
        sets[y as usize] = r;
        y = next;
    }
    r
}

/// Checks that `map` can be labelled by `model`: the model's class names, in order,
/// and at least one place (the map part of [`check_inputs`]).
pub fn check_map(model: &TreeMixture, map: &TopoMap) -> Result<(), TreeMixError> {
    Ok(map.check_labellable(&model.classes)?)
}

/// Checks that `model`, `map` and `trees` fit together: a valid model, the same class
/// names, a map with places and at least one spanning forest, each of them a forest of
/// `map`. The interpreter (`TreeInstance::build`) and the code generator both run it.
pub fn check_inputs(
    model: &TreeMixture,
    map: &TopoMap,
    trees: &SpanningTrees,
) -> Result<(), TreeMixError> {
    model
        .check("<model>")
        .map_err(|e| TreeMixError::Model(e.to_string()))?;
    check_map(model, map)?;
    if trees.is_empty() {
        return Err(TreeMixError::BadTrees(
            "a tree mixture needs at least one tree".into(),
        ));
    }
    trees.check_fits(map)
}
