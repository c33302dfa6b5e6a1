//! Building and growing [`TopoMap`]s, and graph queries on them.

use std::collections::BTreeSet;

use petgraph::graph::{NodeIndex, UnGraph};

use super::{ClassSet, MapError, Place, PlaceId, TopoMap};

impl TopoMap {
    /// A map from places and undirected edges given as place-id pairs.
    ///
    /// Places are sorted by id (the place order); edges are de-duplicated
    /// (`(a, b)` and `(b, a)` are the same edge) and added in sorted order.
    /// Errors: duplicate place ids, self-loops, edge endpoints that name no
    /// place, class indices out of range, non-finite poses.
    pub fn new(
        name: impl Into<String>,
        classes: ClassSet,
        mut places: Vec<Place>,
        edges: Vec<(PlaceId, PlaceId)>,
    ) -> Result<TopoMap, MapError> {
        places.sort_by_key(|p| p.id);
        for w in places.windows(2) {
            if w[0].id == w[1].id {
                return Err(MapError::DuplicatePlace { id: w[0].id });
            }
        }
        for p in &places {
            check_place(p, &classes)?;
        }
        let ids: Vec<PlaceId> = places.iter().map(|p| p.id).collect();
        let mut pairs = BTreeSet::new();
        for (a, b) in edges {
            if a == b {
                return Err(MapError::SelfLoop { id: a });
            }
            let ia = ids
                .binary_search(&a)
                .map_err(|_| MapError::MissingEndpoint { a, b, missing: a })?;
            let ib = ids
                .binary_search(&b)
                .map_err(|_| MapError::MissingEndpoint { a, b, missing: b })?;
            pairs.insert((ia.min(ib), ia.max(ib)));
        }
        let mut graph = UnGraph::with_capacity(places.len(), pairs.len());
        for p in places {
            graph.add_node(p);
        }
        for (a, b) in pairs {
            graph.add_edge(NodeIndex::new(a), NodeIndex::new(b), ());
        }
        Ok(TopoMap {
            name: name.into(),
            classes,
            graph,
        })
    }

    /// Index (in place order) of the place with id `id`.
    ///
    /// Binary search, as place order is sorted by id for every map built by
    /// [`TopoMap::new`], the loaders and [`TopoMap::add_place`]; falls back to
    /// a linear scan for a graph assembled by hand out of order.
    pub fn index_of_id(&self, id: PlaceId) -> Option<usize> {
        let n = self.num_places();
        let (mut lo, mut hi) = (0usize, n);
        while lo < hi {
            let mid = (lo + hi) / 2;
            let m = self.place(mid).id;
            if m == id {
                return Some(mid);
            }
            if m < id {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        self.places().position(|p| p.id == id)
    }

    /// Number of neighbours of place `i`.
    pub fn degree(&self, i: usize) -> usize {
        self.graph.neighbors(NodeIndex::new(i)).count()
    }

    /// Whether places `i` and `j` are joined by an edge.
    pub fn has_edge(&self, i: usize, j: usize) -> bool {
        self.graph
            .find_edge(NodeIndex::new(i), NodeIndex::new(j))
            .is_some()
    }

    /// Undirected edges as index pairs `(i, j)` with `i < j`, sorted.
    pub fn edge_list(&self) -> Vec<(usize, usize)> {
        let mut v: Vec<(usize, usize)> = self
            .graph
            .edge_indices()
            .filter_map(|e| self.graph.edge_endpoints(e))
            .map(|(a, b)| (a.index().min(b.index()), a.index().max(b.index())))
            .collect();
        v.sort_unstable();
        v
    }

    /// Connected components, each a sorted list of place indices; components
    /// are ordered by their smallest index.
    pub fn connected_components(&self) -> Vec<Vec<usize>> {
        let n = self.num_places();
        let mut comp = vec![usize::MAX; n];
        let mut out = Vec::new();
        let mut stack = Vec::new();
        for s in 0..n {
            if comp[s] != usize::MAX {
                continue;
            }
            let c = out.len();
            let mut members = vec![s];
            comp[s] = c;
            stack.push(s);
            while let Some(v) = stack.pop() {
                for w in self.graph.neighbors(NodeIndex::new(v)) {
                    let w = w.index();
                    if comp[w] == usize::MAX {
                        comp[w] = c;
                        members.push(w);
                        stack.push(w);
                    }
                }
            }
            members.sort_unstable();
            out.push(members);
        }
        out
    }

    /// The sub-map induced by the places at `indices` (any order; duplicates
    /// ignored). Place order stays sorted by id; the name and classes are kept.
    pub fn induced_submap(&self, indices: &[usize]) -> TopoMap {
        let keep: BTreeSet<usize> = indices
            .iter()
            .copied()
            .filter(|&i| i < self.num_places())
            .collect();
        let mut new_index = vec![usize::MAX; self.num_places()];
        let mut graph = UnGraph::with_capacity(keep.len(), 0);
        for &i in &keep {
            new_index[i] = graph.add_node(self.place(i).clone()).index();
        }
        for (a, b) in self.edge_list() {
            if new_index[a] != usize::MAX && new_index[b] != usize::MAX {
                graph.add_edge(
                    NodeIndex::new(new_index[a]),
                    NodeIndex::new(new_index[b]),
                    (),
                );
            }
        }
        TopoMap {
            name: self.name.clone(),
            classes: self.classes.clone(),
            graph,
        }
    }

    /// The largest connected component as a map of its own (ties: the
    /// component holding the smallest place index). An empty map stays empty.
    pub fn largest_component(&self) -> TopoMap {
        let comps = self.connected_components();
        let mut best: &[usize] = &[];
        for c in &comps {
            if c.len() > best.len() {
                best = c;
            }
        }
        self.induced_submap(best)
    }

    /// Add a place (a robot discovering a new place). Its id must exceed every
    /// existing id, so place order stays sorted by id and the indices of the
    /// existing places do not change. Returns the new place's index.
    pub fn add_place(&mut self, place: Place) -> Result<usize, MapError> {
        check_place(&place, &self.classes)?;
        if let Some(last) = self.graph.node_weights().map(|p| p.id).max() {
            if place.id == last {
                return Err(MapError::DuplicatePlace { id: place.id });
            }
            if place.id < last {
                return Err(MapError::PlaceIdNotIncreasing {
                    id: place.id,
                    max: last,
                });
            }
        }
        Ok(self.graph.add_node(place).index())
    }

    /// Add an undirected edge between the places with ids `a` and `b`.
    /// Returns `false` when the edge was already present (no parallel edges).
    pub fn add_edge(&mut self, a: PlaceId, b: PlaceId) -> Result<bool, MapError> {
        if a == b {
            return Err(MapError::SelfLoop { id: a });
        }
        let ia = self
            .index_of_id(a)
            .ok_or(MapError::MissingEndpoint { a, b, missing: a })?;
        let ib = self
            .index_of_id(b)
            .ok_or(MapError::MissingEndpoint { a, b, missing: b })?;
        if self.has_edge(ia, ib) {
            return Ok(false);
        }
        self.graph
            .add_edge(NodeIndex::new(ia), NodeIndex::new(ib), ());
        Ok(true)
    }
}

fn check_place(p: &Place, classes: &ClassSet) -> Result<(), MapError> {
    if let Some(c) = p.class
        && c as usize >= classes.len()
    {
        return Err(MapError::ClassOutOfRange {
            id: p.id,
            class: c,
            num_classes: classes.len(),
        });
    }
    if !p.x.is_finite() || !p.y.is_finite() {
        return Err(MapError::NonFinitePose {
            id: p.id,
            x: p.x,
            y: p.y,
        });
    }
    Ok(())
}
