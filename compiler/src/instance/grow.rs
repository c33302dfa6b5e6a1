//! Incremental decompositions for a growing map (a robot exploring).
//!
//! When places are appended and edges added, most of an old decomposition is still a
//! valid partition of the old places (matches are monomorphisms, so added edges never
//! break one). Only the neighbourhood of the change should be redone, so that the
//! instance can keep the template copies of every other component.
//!
//! A place is *touched* when it is new or an endpoint of a new edge. An old component is
//! *dissolved* when it contains a touched place and its template is smaller than the
//! largest template of the list (the first tried by Alg. 2): such a component might
//! now be part of a larger match. Components of the largest template are kept even when
//! touched (nothing larger can form), as are all untouched components. The freed places
//! and the new places are then decomposed among themselves with Alg. 2
//! ([`decompose`]) on the sub-map they induce.

use std::collections::BTreeSet;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::build::edge_set;
use super::query::InstanceQueryError;
use super::{CopyStats, Instance, InstanceError};
use crate::decompose::{Component, Decomposition, decompose};
use crate::learn::Model;
use crate::map::TopoMap;
use crate::template::Template;

/// New decompositions of `grown` (a map whose first `old_places` places and every edge
/// of `old_edges` are unchanged) from the old decompositions of the old map: untouched
/// components are kept verbatim; the freed and new places of decomposition `d` are
/// decomposed with Alg. 2 using `ChaCha8Rng::seed_from_u64(seed)` on stream `d`.
/// See the module documentation for which components are dissolved.
///
/// `old_edges` are (smaller, larger) place-index pairs. Errors if `grown` has fewer
/// places than `old_places` or the decomposition of the freed places fails.
pub fn grow_decompositions(
    old: &[Decomposition],
    old_places: usize,
    old_edges: &BTreeSet<(usize, usize)>,
    grown: &TopoMap,
    templates: &[Template],
    seed: u64,
) -> Result<Vec<Decomposition>, InstanceQueryError> {
    let n = grown.num_places();
    if n < old_places {
        return Err(InstanceError::MapShrank {
            before: old_places,
            after: n,
        }
        .into());
    }
    let mut touched = vec![false; n];
    for t in touched.iter_mut().skip(old_places) {
        *t = true;
    }
    for e in edge_set(grown) {
        if !old_edges.contains(&e) {
            touched[e.0] = true;
            touched[e.1] = true;
        }
    }
    let largest = templates.iter().map(|t| t.num_nodes).max().unwrap_or(0);
    let mut out = Vec::with_capacity(old.len());
    for (d, dec) in old.iter().enumerate() {
        let mut kept: Vec<Component> = Vec::with_capacity(dec.components.len());
        let mut free: Vec<usize> = (old_places..n).collect();
        for comp in &dec.components {
            let small = templates
                .get(comp.template)
                .is_none_or(|t| t.num_nodes < largest);
            if small && comp.places.iter().any(|&p| touched.get(p) == Some(&true)) {
                free.extend(&comp.places);
            } else {
                kept.push(comp.clone());
            }
        }
        free.sort_unstable();
        if !free.is_empty() {
            // induced_submap keeps place order, so sub-map index i is free[i].
            let sub = grown.induced_submap(&free);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(d as u64);
            let part = decompose(&sub, templates, &mut rng).map_err(|source| {
                InstanceQueryError::Decompose {
                    map: grown.name.clone(),
                    source,
                }
            })?;
            kept.extend(part.components.into_iter().map(|c| Component {
                template: c.template,
                places: c.places.iter().map(|&i| free[i]).collect(),
            }));
        }
        out.push(Decomposition { components: kept });
    }
    Ok(out)
}

impl Instance {
    /// Updates the instance after `grown_map` grew from the map it was built for (new
    /// places appended, edges added): new decompositions by [`grow_decompositions`]
    /// (seeded by `seed`), then [`Instance::update`], which keeps the template copies of
    /// every component still used. Returns how many copies were reused and built.
    pub fn grow(
        &mut self,
        model: &Model,
        grown_map: &TopoMap,
        seed: u64,
    ) -> Result<CopyStats, InstanceQueryError> {
        let decompositions = grow_decompositions(
            &self.decompositions,
            self.num_places(),
            &self.edges,
            grown_map,
            &model.templates,
            seed,
        )?;
        self.update(model, grown_map, decompositions)?;
        Ok(self.last_copy_stats())
    }
}
