//! Synthetic office floors: topological maps with COLD-like statistics, of any
//! size, from a seed.
//!
//! The floor is laid out on a square grid of 0.8 m cells (so neighbouring
//! places are 0.8 m or 1.13 m apart, as COLD's anchors). Horizontal corridors,
//! two cells wide, are joined at both ends by vertical corridors (so the floor
//! has loops). Rooms line both sides of every corridor, behind a wall row; a
//! doorway place (DW) in the wall joins each room to the corridor. Each room
//! takes one of the eight room classes, with a size typical of that class in
//! COLD; its places form an 8-neighbourhood grid from which some edges are
//! dropped (a robot's map is not a full lattice). Places in a room's back row
//! become placeholders (frontiers seen but not visited) joined to 1–3 visited
//! places. The map is the first `places` places reached by a breadth-first
//! exploration from the corridor corner, numbered in that order, so every
//! prefix of the place order is connected (as a robot's map grows).
//!
//! Statistics are compared with COLD in [`crate::map::stats`].

use std::collections::{HashMap, VecDeque};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{ClassId, ClassSet, MapError, Place, PlaceId, TopoMap};

/// Grid spacing in metres (COLD anchors: 0.8 m orthogonal, 1.13 m diagonal).
pub const CELL: f64 = 0.8;

/// Smallest and largest supported map sizes.
pub const PLACES_RANGE: std::ops::RangeInclusive<usize> = 10..=100_000;

const DW: ClassId = 0;
const CR: ClassId = 1;

/// Parameters of the synthetic office-floor generator.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticParams {
    /// Number of places, in [`PLACES_RANGE`].
    pub places: usize,
    /// Seed of every random choice; the same parameters give the same map.
    pub seed: u64,
    /// Probability that a diagonal edge of the place grid is kept (0..=1).
    pub diagonal_keep: f64,
    /// Probability that an orthogonal edge inside a room is kept (0..=1).
    pub orthogonal_keep: f64,
    /// Probability that a back-row room place is a placeholder (0..=1).
    pub placeholder_prob: f64,
    /// Probability that an upper-row corridor place (not next to a doorway)
    /// is a placeholder (0..=1).
    pub corridor_placeholder_prob: f64,
    /// Probability that a room slot along a corridor is left blank (0..=1).
    pub blank_wall: f64,
}

impl SyntheticParams {
    /// Defaults tuned so the statistics match COLD's (see [`crate::map::stats`]).
    pub fn new(places: usize, seed: u64) -> Self {
        SyntheticParams {
            places,
            seed,
            diagonal_keep: 0.6,
            orthogonal_keep: 0.8,
            placeholder_prob: 0.95,
            corridor_placeholder_prob: 0.9,
            blank_wall: 0.25,
        }
    }

    fn validate(&self) -> Result<(), MapError> {
        if !PLACES_RANGE.contains(&self.places) {
            return Err(MapError::SyntheticParams(format!(
                "places = {} is outside {}..={}",
                self.places,
                PLACES_RANGE.start(),
                PLACES_RANGE.end()
            )));
        }
        for (name, p) in [
            ("diagonal_keep", self.diagonal_keep),
            ("orthogonal_keep", self.orthogonal_keep),
            ("placeholder_prob", self.placeholder_prob),
            ("corridor_placeholder_prob", self.corridor_placeholder_prob),
            ("blank_wall", self.blank_wall),
        ] {
            if !(0.0..=1.0).contains(&p) {
                return Err(MapError::SyntheticParams(format!(
                    "{name} = {p} is not a probability"
                )));
            }
        }
        Ok(())
    }
}

/// Room classes with relative frequency of rooms and size ranges (cells along
/// the corridor, cells deep), chosen so node shares and room sizes resemble COLD.
/// A room kind: class, relative frequency, width range, depth range (cells).
type RoomKind = (ClassId, f64, (i32, i32), (i32, i32));

const ROOMS: [RoomKind; 8] = [
    (2, 1.15, (2, 3), (3, 4)), // 1PO
    (3, 1.00, (3, 3), (3, 4)), // 2PO
    (4, 0.17, (4, 5), (4, 5)), // LO
    (5, 0.50, (4, 5), (4, 5)), // LAB
    (6, 0.85, (2, 3), (2, 3)), // BA
    (7, 0.34, (3, 5), (4, 4)), // KT
    (8, 0.30, (3, 4), (4, 5)), // MR
    (9, 0.95, (3, 3), (3, 4)), // UT
];
const MAX_DEPTH: i32 = 5;
/// Rows between corridor k and k+1: corridor (2) + wall + room + gap + room + wall.
const PERIOD: i32 = 2 + 1 + MAX_DEPTH + 1 + MAX_DEPTH + 1;

struct Cell {
    gx: i32,
    gy: i32,
    class: ClassId,
    placeholder: bool,
}

struct Floor {
    cells: Vec<Cell>,
    at: HashMap<(i32, i32), usize>,
    adj: Vec<Vec<usize>>,
}

impl Floor {
    fn add(&mut self, gx: i32, gy: i32, class: ClassId) -> usize {
        if let Some(&i) = self.at.get(&(gx, gy)) {
            return i;
        }
        let i = self.cells.len();
        self.cells.push(Cell {
            gx,
            gy,
            class,
            placeholder: false,
        });
        self.adj.push(Vec::new());
        self.at.insert((gx, gy), i);
        i
    }

    fn link(&mut self, a: usize, b: usize) {
        if a != b && !self.adj[a].contains(&b) {
            self.adj[a].push(b);
            self.adj[b].push(a);
        }
    }

    fn unlink(&mut self, a: usize, b: usize) {
        self.adj[a].retain(|&x| x != b);
        self.adj[b].retain(|&x| x != a);
    }

    /// Join the cells in `ids` to their same-class grid neighbours (8-neighbourhood),
    /// keeping orthogonal edges with `po` and diagonal ones with `pd`.
    fn lattice(&mut self, ids: &[usize], po: f64, pd: f64, rng: &mut ChaCha8Rng) {
        for &a in ids {
            let (x, y) = (self.cells[a].gx, self.cells[a].gy);
            // Each unordered pair once: right, up, up-right, up-left.
            for (dx, dy, diag) in [(1, 0, false), (0, 1, false), (1, 1, true), (-1, 1, true)] {
                if let Some(&b) = self.at.get(&(x + dx, y + dy)) {
                    // Only within one region: rooms and corridors are kept
                    // apart by wall rows and columns, and differ in class.
                    if self.cells[b].class != self.cells[a].class {
                        continue;
                    }
                    let p = if diag { pd } else { po };
                    if rng.random_bool(p) {
                        self.link(a, b);
                    }
                }
            }
        }
    }
}

fn pick_room(rng: &mut ChaCha8Rng) -> (ClassId, i32, i32) {
    let total: f64 = ROOMS.iter().map(|r| r.1).sum();
    let mut u = rng.random_range(0.0..total);
    let mut chosen = ROOMS[0];
    for r in ROOMS {
        if u < r.1 {
            chosen = r;
            break;
        }
        u -= r.1;
    }
    let (c, _, (w0, w1), (h0, h1)) = chosen;
    (c, rng.random_range(w0..=w1), rng.random_range(h0..=h1))
}

/// Lay out a floor of `corridors` corridors of `length` cells each.
fn build_floor(p: &SyntheticParams, corridors: i32, length: i32, rng: &mut ChaCha8Rng) -> Floor {
    let mut f = Floor {
        cells: Vec::new(),
        at: HashMap::new(),
        adj: Vec::new(),
    };
    let pd = p.diagonal_keep;
    // Corridors: horizontal ones at rows k*PERIOD, k*PERIOD+1; vertical ones at
    // columns -2,-1 and length, length+1 spanning all corridor rows.
    let top = (corridors - 1) * PERIOD + 1;
    let mut corridor = Vec::new();
    for k in 0..corridors {
        for x in -2..length + 2 {
            for dy in 0..2 {
                corridor.push(f.add(x, k * PERIOD + dy, CR));
            }
        }
    }
    for x in [-2, -1, length, length + 1] {
        for y in 0..=top {
            corridor.push(f.add(x, y, CR));
        }
    }
    // Corridors: all orthogonal edges (a corridor is traversed), diagonals thinned.
    f.lattice(&corridor, 1.0, pd, rng);

    for k in 0..corridors {
        let base = k * PERIOD;
        // side = +1: rooms above the corridor; -1: below (not below corridor 0's
        // floor edge: there are rooms there too, the floor just extends).
        for side in [1, -1] {
            let mut x = 0;
            loop {
                let (class, w, h) = pick_room(rng);
                if x + w > length {
                    break;
                }
                if rng.random_bool(p.blank_wall) {
                    // A stretch of wall without a mapped room (stairs, shafts).
                    x += w + 1;
                    continue;
                }
                // Row of the wall (doorway) and the room's rows, outward from the corridor.
                let wall = if side > 0 { base + 2 } else { base - 1 };
                let row = |d: i32| wall + side * (1 + d);
                let mut room = Vec::new();
                for d in 0..h {
                    for dx in 0..w {
                        room.push(f.add(x + dx, row(d), class));
                    }
                }
                f.lattice(&room, p.orthogonal_keep, pd, rng);
                // Keep the room connected to its door row: every cell of row d
                // keeps its orthogonal edge towards the door (row d-1), so the
                // room is a union of trees hanging off the first row, and the
                // first row is a path.
                for d in 0..h {
                    for dx in 0..w {
                        let a = f.at[&(x + dx, row(d))];
                        if d == 0 {
                            if dx > 0 {
                                let b = f.at[&(x + dx - 1, row(0))];
                                f.link(a, b);
                            }
                        } else {
                            let b = f.at[&(x + dx, row(d - 1))];
                            f.link(a, b);
                        }
                    }
                }
                // Doorway: one place in the wall row, sometimes two side by side.
                let door_x = x + rng.random_range(0..w);
                let mut doors = vec![f.add(door_x, wall, DW)];
                if w >= 3 && rng.random_bool(0.1) {
                    let x2 = if door_x + 1 < x + w {
                        door_x + 1
                    } else {
                        door_x - 1
                    };
                    let d2 = f.add(x2, wall, DW);
                    f.link(doors[0], d2);
                    doors.push(d2);
                }
                for &dw in &doors {
                    let dx0 = f.cells[dw].gx;
                    for ddx in -1..=1 {
                        let diag = ddx != 0;
                        let keep = |rng: &mut ChaCha8Rng| !diag || rng.random_bool(pd);
                        if let Some(&c) = f.at.get(&(dx0 + ddx, wall - side))
                            && keep(rng)
                        {
                            f.link(dw, c);
                        }
                        if let Some(&r) = f.at.get(&(dx0 + ddx, row(0)))
                            && f.cells[r].class == class
                            && keep(rng)
                        {
                            f.link(dw, r);
                        }
                    }
                }
                // Placeholders: back-row places seen from the row in front.
                if h >= 2 {
                    for dx in 0..w {
                        if !rng.random_bool(p.placeholder_prob) {
                            continue;
                        }
                        let a = f.at[&(x + dx, row(h - 1))];
                        f.cells[a].placeholder = true;
                        // A frontier is seen from 1–3 visited places only.
                        let keep_n = frontier_links(rng);
                        let front = f.at[&(x + dx, row(h - 2))];
                        let mut others: Vec<usize> =
                            f.adj[a].iter().copied().filter(|&b| b != front).collect();
                        others.sort_unstable();
                        let mut kept = 1;
                        for b in others {
                            if kept < keep_n && !f.cells[b].placeholder {
                                kept += 1;
                            } else {
                                f.unlink(a, b);
                            }
                        }
                    }
                }
                x += w + 1;
            }
        }
        // Corridor frontiers: upper-row corridor places seen from the row below.
        for x in 0..length {
            let a = f.at[&(x, base + 1)];
            let front = f.at[&(x, base)];
            let near_door = f.adj[a].iter().any(|&b| f.cells[b].class == DW);
            if near_door || !rng.random_bool(p.corridor_placeholder_prob) {
                continue;
            }
            f.cells[a].placeholder = true;
            let keep_n = frontier_links(rng);
            let mut others: Vec<usize> = f.adj[a].iter().copied().filter(|&b| b != front).collect();
            others.sort_unstable();
            let mut kept = 1;
            for b in others {
                if kept < keep_n && !f.cells[b].placeholder {
                    kept += 1;
                } else {
                    f.unlink(a, b);
                }
            }
        }
    }
    f
}

/// How many visited places a frontier is seen from: 1 (50%), 2 (30%), 3 (20%).
fn frontier_links(rng: &mut ChaCha8Rng) -> usize {
    match rng.random_range(0.0..1.0) {
        u if u < 0.5 => 1,
        u if u < 0.8 => 2,
        _ => 3,
    }
}

/// Generate a synthetic office floor with exactly `params.places` places and
/// the paper's ten classes. Deterministic in the parameters.
pub fn generate(params: &SyntheticParams) -> Result<TopoMap, MapError> {
    params.validate()?;
    let n = params.places;
    // About 5.5 places per corridor cell of length (both room sides and the
    // corridor); aim at a roughly square floor with 10% spare places.
    const PER_CELL: f64 = 5.5;
    let want = (n as f64 * 1.1).max(30.0);
    let corridors = ((want / (PER_CELL * PERIOD as f64)).sqrt().round() as i32).max(1);
    let mut length = ((want / (PER_CELL * corridors as f64)).ceil() as i32).max(6);
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    loop {
        let floor = build_floor(params, corridors, length, &mut rng);
        if let Some(map) = explore(&floor, n, params.seed) {
            return map;
        }
        // Not enough places reachable: grow the floor and retry (deterministic).
        length += length / 8 + 2;
    }
}

/// Round metres to millimetres (short, exact JSON).
fn mm(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

/// Breadth-first exploration from the corridor corner; the first `n` places in
/// that order, numbered 0..n. `None` if fewer than `n` are reachable.
fn explore(f: &Floor, n: usize, seed: u64) -> Option<Result<TopoMap, MapError>> {
    let start = *f.at.get(&(-2, 0))?;
    let mut order = Vec::with_capacity(n);
    let mut number = vec![usize::MAX; f.cells.len()];
    let mut queue = VecDeque::from([start]);
    number[start] = 0;
    while let Some(v) = queue.pop_front() {
        order.push(v);
        if order.len() == n {
            break;
        }
        let mut nb = f.adj[v].clone();
        nb.sort_unstable();
        for w in nb {
            if number[w] == usize::MAX {
                number[w] = 0;
                queue.push_back(w);
            }
        }
    }
    if order.len() < n {
        return None;
    }
    for (k, &v) in order.iter().enumerate() {
        number[v] = k;
    }
    let in_map = |v: usize| number[v] != usize::MAX && number[v] < n && order[number[v]] == v;
    // Small deterministic jitter (< 8 cm, rounded to mm) so the drawing looks
    // hand-made, not a lattice.
    let mut jrng = ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
    let places: Vec<Place> = order
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            let c = &f.cells[v];
            Place {
                id: k as PlaceId,
                class: Some(c.class),
                placeholder: c.placeholder,
                x: mm(c.gx as f64 * CELL + jrng.random_range(-0.08..0.08)),
                y: mm(c.gy as f64 * CELL + jrng.random_range(-0.08..0.08)),
            }
        })
        .collect();
    let mut edges = Vec::new();
    for &v in &order {
        for &w in &f.adj[v] {
            if v < w && in_map(w) {
                edges.push((number[v] as PlaceId, number[w] as PlaceId));
            }
        }
    }
    Some(TopoMap::new(
        format!("synthetic/n{n}_seed{seed}"),
        ClassSet::paper(),
        places,
        edges,
    ))
}
