//! Sub-graph templates: small graph shapes whose copies tile a map.
//!
//! A template has nodes `0..num_nodes` in a canonical variable order and an edge
//! list. A *match* in a map is an injective map from template nodes to places
//! such that every template edge is a map edge (a subgraph monomorphism: extra
//! map edges between matched places are allowed, as in the paper's Three where
//! A and B may be adjacent).

use serde::{Deserialize, Serialize};

/// A sub-graph template.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Template {
    /// Unique name, e.g. `star`.
    pub name: String,
    /// Number of nodes; node `i` is variable `i` of the template SPN.
    pub num_nodes: usize,
    /// Undirected edges between template nodes, each `(a, b)` with `a < b`.
    pub edges: Vec<(usize, usize)>,
}

impl Template {
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
