//! Decompositions of a map into template-shaped components (the paper's Alg. 2).
//!
//! - [`decompose`]: one random decomposition (greedy, templates largest first).
//! - [`decompose_best`]: the authors' best-of-N scheme: N random partitions by the
//!   largest template, the K with the highest coverage kept, each completed with
//!   the smaller templates.
//! - [`Decomposition::validate`]: partition and match checks, independent of
//!   the matcher.
//! - [`file`](mod@file): the versioned JSON format (template names and place ids).
//! - [`synthetic`]: random connected graphs and grids for tests and benchmarks.

use serde::{Deserialize, Serialize};

use crate::map::{PlaceId, TopoMap};
use crate::template::{Template, TemplateError};

pub mod file;
mod greedy;
pub mod synthetic;

pub use greedy::{
    DecompositionParams, DecompositionStrategy, MAX_CANDIDATES, MAX_DECOMPOSITIONS, decompose,
    decompose_best, template_shares,
};

/// One component of a decomposition: a copy of a template placed on the map.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Component {
    /// Index of the template in the template list the decomposition was made with.
    pub template: usize,
    /// Place indices (map place order), in the template's canonical node order.
    pub places: Vec<usize>,
}

/// A partition of all places of a map into template-shaped components.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Decomposition {
    /// The components; every place appears in exactly one.
    pub components: Vec<Component>,
}

fn fmt_place(index: usize, id: &Option<PlaceId>) -> String {
    match id {
        Some(id) => format!("place id {id} (index {index})"),
        None => format!("place index {index}"),
    }
}

/// Why a decomposition could not be made or is not valid.
#[derive(Debug, thiserror::Error)]
pub enum DecomposeError {
    /// A template is malformed.
    #[error(transparent)]
    Template(#[from] TemplateError),
    /// The template list is empty.
    #[error("the template list is empty")]
    NoTemplates,
    /// Two templates share a name (names identify templates in files).
    #[error("two templates are called {name:?}")]
    DuplicateTemplateName {
        /// The name.
        name: String,
    },
    /// No 1-node template: the greedy decomposition could leave places uncovered.
    #[error(
        "the template list has no 1-node template, so a decomposition might not cover every place"
    )]
    NoSingleton,
    /// Invalid [`DecompositionParams`].
    #[error("invalid decomposition parameters: {0}")]
    BadParams(String),
    /// A component names a template index outside the list.
    #[error(
        "component {component} uses template index {template}, but there are only {num_templates} templates"
    )]
    UnknownTemplate {
        /// Component index.
        component: usize,
        /// Its template index.
        template: usize,
        /// Length of the template list.
        num_templates: usize,
    },
    /// A component names a place index outside the map.
    #[error("component {component} uses place index {place}, but the map has {num_places} places")]
    PlaceOutOfRange {
        /// Component index.
        component: usize,
        /// The place index.
        place: usize,
        /// Number of places of the map.
        num_places: usize,
    },
    /// A place is in two components (or twice in one).
    #[error("{} is covered twice: by components {first} and {second}", fmt_place(*place, id))]
    PlaceCoveredTwice {
        /// Place index.
        place: usize,
        /// Its id, when the map is known.
        id: Option<PlaceId>,
        /// First component covering it.
        first: usize,
        /// Second component covering it.
        second: usize,
    },
    /// A place is in no component.
    #[error("{} is not covered by any component", fmt_place(*place, id))]
    PlaceNotCovered {
        /// Place index.
        place: usize,
        /// Its id, when the map is known.
        id: Option<PlaceId>,
    },
    /// A component is not a match of its template.
    #[error("component {component} is not a match of template {template:?}: {reason}")]
    NotAMatch {
        /// Component index.
        component: usize,
        /// Template name.
        template: String,
        /// What is wrong.
        reason: String,
    },
}

impl Decomposition {
    /// For each place index `0..num_places`, the index of the component that
    /// covers it. Fails if a component uses an out-of-range place, or a place is
    /// covered twice or not at all.
    pub fn component_of_place(&self, num_places: usize) -> Result<Vec<usize>, DecomposeError> {
        self.partition(num_places, None)
    }

    fn partition(
        &self,
        num_places: usize,
        map: Option<&TopoMap>,
    ) -> Result<Vec<usize>, DecomposeError> {
        let id = |p: usize| map.map(|m| m.place(p).id);
        let mut owner = vec![usize::MAX; num_places];
        for (c, comp) in self.components.iter().enumerate() {
            for &p in &comp.places {
                if p >= num_places {
                    return Err(DecomposeError::PlaceOutOfRange {
                        component: c,
                        place: p,
                        num_places,
                    });
                }
                if owner[p] != usize::MAX {
                    return Err(DecomposeError::PlaceCoveredTwice {
                        place: p,
                        id: id(p),
                        first: owner[p],
                        second: c,
                    });
                }
                owner[p] = c;
            }
        }
        if let Some(p) = owner.iter().position(|&o| o == usize::MAX) {
            return Err(DecomposeError::PlaceNotCovered {
                place: p,
                id: id(p),
            });
        }
        Ok(owner)
    }

    /// Checks that this is a valid decomposition of `map` by `templates`: every
    /// component names a template of the list, is a match of it (right size,
    /// distinct places, every template edge a map edge — checked with
    /// [`Template::mismatch`], not with the matcher), and the components
    /// partition all places.
    pub fn validate(&self, map: &TopoMap, templates: &[Template]) -> Result<(), DecomposeError> {
        for (c, comp) in self.components.iter().enumerate() {
            let t = templates
                .get(comp.template)
                .ok_or(DecomposeError::UnknownTemplate {
                    component: c,
                    template: comp.template,
                    num_templates: templates.len(),
                })?;
            if let Some(reason) = t.mismatch(&comp.places, map) {
                return Err(DecomposeError::NotAMatch {
                    component: c,
                    template: t.name.clone(),
                    reason,
                });
            }
        }
        self.partition(map.num_places(), Some(map))?;
        Ok(())
    }

    /// Number of places covered by components of each template
    /// `0..num_templates` (components with other template indices are ignored).
    pub fn template_node_counts(&self, num_templates: usize) -> Vec<usize> {
        let mut counts = vec![0; num_templates];
        for comp in &self.components {
            if let Some(c) = counts.get_mut(comp.template) {
                *c += comp.places.len();
            }
        }
        counts
    }

    /// Share of the covered places that lie in components of each template
    /// `0..num_templates` (sums to 1 for a non-empty valid decomposition).
    pub fn template_shares(&self, num_templates: usize) -> Vec<f64> {
        let counts = self.template_node_counts(num_templates);
        let total: usize = self.components.iter().map(|c| c.places.len()).sum();
        counts
            .iter()
            .map(|&c| {
                if total == 0 {
                    0.0
                } else {
                    c as f64 / total as f64
                }
            })
            .collect()
    }
}
