//! Sub-graph templates: small graph shapes whose copies tile a map.
//!
//! A template has nodes `0..num_nodes` in a canonical variable order and an edge
//! list. A *match* in a map is an injective map from template nodes to places
//! such that every template edge is a map edge (a subgraph monomorphism: extra
//! map edges between matched places are allowed, as in the paper's Three where
//! A and B may be adjacent).

use serde::{Deserialize, Serialize};

use crate::map::TopoMap;

mod matcher;

pub use matcher::{Adjacency, Matcher};

/// Largest template [`Template::custom`] accepts. Automorphism groups (needed to
/// augment training data) grow like `n!`, and a template SPN over more places
/// would be impractically large anyway.
pub const MAX_TEMPLATE_NODES: usize = 8;

/// Why a template is not usable.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TemplateError {
    /// The template name is empty or contains only white space.
    #[error("template name must not be empty")]
    EmptyName,
    /// The template has no nodes.
    #[error("template {name:?} has no nodes")]
    NoNodes {
        /// Template name.
        name: String,
    },
    /// The template is larger than [`MAX_TEMPLATE_NODES`].
    #[error("template {name:?} has {num_nodes} nodes; at most {max} are supported")]
    TooLarge {
        /// Template name.
        name: String,
        /// Its node count.
        num_nodes: usize,
        /// The limit.
        max: usize,
    },
    /// An edge names a node outside `0..num_nodes`.
    #[error("template {name:?}: edge ({a}, {b}) is out of range (nodes are 0..{num_nodes})")]
    EdgeOutOfRange {
        /// Template name.
        name: String,
        /// First end.
        a: usize,
        /// Second end.
        b: usize,
        /// Node count.
        num_nodes: usize,
    },
    /// An edge joins a node to itself.
    #[error("template {name:?}: self-loop on node {node}")]
    SelfLoop {
        /// Template name.
        name: String,
        /// The node.
        node: usize,
    },
    /// The same undirected edge is listed twice.
    #[error("template {name:?}: edge ({a}, {b}) is listed twice")]
    DuplicateEdge {
        /// Template name.
        name: String,
        /// Smaller end.
        a: usize,
        /// Larger end.
        b: usize,
    },
    /// Edges are not stored as sorted `(a, b)` pairs with `a < b` (only reported
    /// by [`Template::validate`]; [`Template::custom`] normalises them).
    #[error("template {name:?}: edges must be sorted pairs (a, b) with a < b")]
    NotNormalised {
        /// Template name.
        name: String,
    },
    /// Some node cannot be reached from node 0.
    #[error("template {name:?} is not connected: node {node} is unreachable from node 0")]
    Disconnected {
        /// Template name.
        name: String,
        /// An unreachable node.
        node: usize,
    },
}

/// A sub-graph template.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Template {
    /// Unique name, e.g. `star`.
    pub name: String,
    /// Number of nodes; node `i` is variable `i` of the template SPN.
    pub num_nodes: usize,
    /// Undirected edges between template nodes, each `(a, b)` with `a < b`.
    pub edges: Vec<(usize, usize)>,
}

impl Template {
    /// A user-defined template: `num_nodes` nodes (`1..=`[`MAX_TEMPLATE_NODES`])
    /// joined by `edges` (either orientation). Checks that edges are in range,
    /// without self-loops or duplicates, and that the template is connected;
    /// stores edges as sorted `(a, b)` pairs with `a < b`. Node 0 is the pivot
    /// at which matches are rooted.
    pub fn custom(
        name: impl Into<String>,
        num_nodes: usize,
        edges: &[(usize, usize)],
    ) -> Result<Template, TemplateError> {
        let name = name.into();
        let mut norm = Vec::with_capacity(edges.len());
        for &(a, b) in edges {
            if a >= num_nodes || b >= num_nodes {
                return Err(TemplateError::EdgeOutOfRange {
                    name,
                    a,
                    b,
                    num_nodes,
                });
            }
            if a == b {
                return Err(TemplateError::SelfLoop { name, node: a });
            }
            norm.push((a.min(b), a.max(b)));
        }
        norm.sort_unstable();
        for w in norm.windows(2) {
            if w[0] == w[1] {
                let (a, b) = w[0];
                return Err(TemplateError::DuplicateEdge { name, a, b });
            }
        }
        let t = Template {
            name,
            num_nodes,
            edges: norm,
        };
        t.validate()?;
        Ok(t)
    }

    /// Checks the invariants [`Template::custom`] establishes (useful for
    /// templates read from a file): non-empty name, `1..=MAX_TEMPLATE_NODES`
    /// nodes, sorted in-range edges `(a, b)` with `a < b`, no duplicates, connected.
    pub fn validate(&self) -> Result<(), TemplateError> {
        let name = || self.name.clone();
        if self.name.trim().is_empty() {
            return Err(TemplateError::EmptyName);
        }
        if self.num_nodes == 0 {
            return Err(TemplateError::NoNodes { name: name() });
        }
        if self.num_nodes > MAX_TEMPLATE_NODES {
            return Err(TemplateError::TooLarge {
                name: name(),
                num_nodes: self.num_nodes,
                max: MAX_TEMPLATE_NODES,
            });
        }
        for &(a, b) in &self.edges {
            if a >= self.num_nodes || b >= self.num_nodes {
                return Err(TemplateError::EdgeOutOfRange {
                    name: name(),
                    a,
                    b,
                    num_nodes: self.num_nodes,
                });
            }
            if a == b {
                return Err(TemplateError::SelfLoop {
                    name: name(),
                    node: a,
                });
            }
            if a > b {
                return Err(TemplateError::NotNormalised { name: name() });
            }
        }
        for w in self.edges.windows(2) {
            if w[0] == w[1] {
                return Err(TemplateError::DuplicateEdge {
                    name: name(),
                    a: w[0].0,
                    b: w[0].1,
                });
            }
            if w[0] > w[1] {
                return Err(TemplateError::NotNormalised { name: name() });
            }
        }
        // Connectivity: flood fill from node 0.
        let adj = self.adjacency_matrix();
        let mut seen = vec![false; self.num_nodes];
        let mut stack = vec![0];
        seen[0] = true;
        while let Some(u) = stack.pop() {
            for v in 0..self.num_nodes {
                if adj[u][v] && !seen[v] {
                    seen[v] = true;
                    stack.push(v);
                }
            }
        }
        if let Some(node) = seen.iter().position(|s| !s) {
            return Err(TemplateError::Disconnected { name: name(), node });
        }
        Ok(())
    }

    /// Number of edges.
    pub fn num_edges(&self) -> usize {
        self.edges.len()
    }

    /// Symmetric `num_nodes × num_nodes` adjacency matrix of the template.
    pub fn adjacency_matrix(&self) -> Vec<Vec<bool>> {
        let mut m = vec![vec![false; self.num_nodes]; self.num_nodes];
        for &(a, b) in &self.edges {
            if a < self.num_nodes && b < self.num_nodes {
                m[a][b] = true;
                m[b][a] = true;
            }
        }
        m
    }

    /// All automorphisms of the template: permutations `π` (as `π[i]` = image of
    /// node `i`) that map the edge set onto itself. Sorted lexicographically, so
    /// the identity comes first. Pair: 2, Three: 2 (A↔B), Star: 24.
    ///
    /// Computed by backtracking over partial permutations in lexicographic order,
    /// pruning as soon as an edge between assigned nodes is not preserved; the
    /// output has at most `num_nodes!` entries (40,320 for the 8-node limit).
    pub fn automorphisms(&self) -> Vec<Vec<usize>> {
        let n = self.num_nodes;
        let adj = self.adjacency_matrix();
        let degree: Vec<usize> = adj
            .iter()
            .map(|r| r.iter().filter(|&&x| x).count())
            .collect();
        let mut out = Vec::new();
        let mut perm = Vec::with_capacity(n);
        let mut taken = vec![false; n];
        fn rec(
            adj: &[Vec<bool>],
            degree: &[usize],
            perm: &mut Vec<usize>,
            taken: &mut [bool],
            out: &mut Vec<Vec<usize>>,
        ) {
            let n = adj.len();
            let i = perm.len();
            if i == n {
                out.push(perm.clone());
                return;
            }
            for img in 0..n {
                if taken[img] || degree[img] != degree[i] {
                    continue;
                }
                // Adjacency to every earlier node must be preserved both ways
                // (a bijection preserving adjacency and non-adjacency).
                if (0..i).any(|j| adj[i][j] != adj[img][perm[j]]) {
                    continue;
                }
                taken[img] = true;
                perm.push(img);
                rec(adj, degree, perm, taken, out);
                perm.pop();
                taken[img] = false;
            }
        }
        rec(&adj, &degree, &mut perm, &mut taken, &mut out);
        out
    }

    /// Whether `places` (indices in map place order, in template node order) is
    /// a match of this template in `map`: the right length, pairwise distinct,
    /// in range, and every template edge is a map edge. Extra map edges between
    /// the places are allowed (a monomorphic image, as the decomposition needs).
    ///
    /// Written independently of [`Matcher`], so it can check its results.
    pub fn is_isomorphic_to(&self, places: &[usize], map: &TopoMap) -> bool {
        self.mismatch(places, map).is_none()
    }

    /// Why `places` is not a match of this template in `map` (see
    /// [`Template::is_isomorphic_to`]), or `None` when it is.
    pub fn mismatch(&self, places: &[usize], map: &TopoMap) -> Option<String> {
        use petgraph::graph::NodeIndex;
        if places.len() != self.num_nodes {
            return Some(format!(
                "template {:?} has {} nodes but the component has {} places",
                self.name,
                self.num_nodes,
                places.len()
            ));
        }
        let n = map.num_places();
        for (i, &p) in places.iter().enumerate() {
            if p >= n {
                return Some(format!(
                    "template node {i} maps to place index {p}, but the map has {n} places"
                ));
            }
            if places[..i].contains(&p) {
                return Some(format!(
                    "place id {} appears twice in the component",
                    map.place(p).id
                ));
            }
        }
        for &(a, b) in &self.edges {
            let (pa, pb) = (places[a], places[b]);
            if map
                .graph
                .find_edge(NodeIndex::new(pa), NodeIndex::new(pb))
                .is_none()
            {
                return Some(format!(
                    "template edge ({a}, {b}) of {:?} maps to places {} and {}, which are not adjacent",
                    self.name,
                    map.place(pa).id,
                    map.place(pb).id
                ));
            }
        }
        None
    }

    /// One node: `P`.
    pub fn singleton() -> Self {
        Template {
            name: "singleton".into(),
            num_nodes: 1,
            edges: vec![],
        }
    }

    /// Two adjacent nodes `P–A`, canonical order `[P, A]`.
    pub fn pair() -> Self {
        Template {
            name: "pair".into(),
            num_nodes: 2,
            edges: vec![(0, 1)],
        }
    }

    /// A path `A–P–B` through pivot `P`, canonical order `[P, A, B]`.
    pub fn three() -> Self {
        Template {
            name: "three".into(),
            num_nodes: 3,
            edges: vec![(0, 1), (0, 2)],
        }
    }

    /// Pivot `P` with four neighbours, canonical order `[P, A, B, C, D]`.
    pub fn star() -> Self {
        Template {
            name: "star".into(),
            num_nodes: 5,
            edges: vec![(0, 1), (0, 2), (0, 3), (0, 4)],
        }
    }

    /// The paper's four templates, largest first: Star, Three, Pair, Singleton.
    pub fn paper_set() -> Vec<Template> {
        vec![
            Template::star(),
            Template::three(),
            Template::pair(),
            Template::singleton(),
        ]
    }
}
