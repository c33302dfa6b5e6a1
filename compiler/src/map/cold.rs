//! Loader for the COLD topological maps (`nodes.dat` + `rooms.dat`), with the
//! filtering the paper's authors applied (described in `docs/FORMATS.md`).
//!
//! `nodes.dat` has one place per line in 34 space-separated columns: id,
//! placeholder flag, pose x y, two unused, anchor pose x y, raw label,
//! timestamp, then eight `(neighbor_id, affordance, view_number)` triples
//! (`neighbor_id = -1` marks an empty slot). `rooms.dat` has `node_id room_id`
//! lines with room ids `floor-LABEL-k`.
//!
//! How the two files relate: in all 90 sequences the LABEL part of a node's
//! room id equals the raw label in column 8 of `nodes.dat`, so `rooms.dat`
//! adds only the grouping of places into rooms. The loader checks that
//! agreement ([`MapError::RoomLabelMismatch`]). The authors' one relabelling,
//! room `7-2PO-1` → `7-1PO-3` (Stockholm floor 7, 85 nodes in 8 sequences),
//! therefore changes the class of that room's nodes from 2PO to 1PO.
//!
//! Filtering, in order: raw labels are mapped to the ten classes
//! ([`raw_label_class`]); nodes labelled `UN` are dropped with their edges;
//! edges are the union of both listing directions, de-duplicated; nodes left
//! without an edge are dropped; placeholders are kept; the largest connected
//! component is kept (with the real data it is always the whole graph).
//! [`load_sequence_report`] lists what was dropped; the command-line tool warns
//! when a map loses places to disconnection.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::{ClassId, ClassSet, MapError, Place, PlaceId, TopoMap};

/// The three COLD buildings, in the order [`load_all`] returns them.
pub const BUILDINGS: [&str; 3] = ["Freiburg", "Saarbrucken", "Stockholm"];

/// Number of columns of a `nodes.dat` line.
pub const NODE_COLUMNS: usize = 34;

/// Environment variable naming the COLD data folder (overrides the shipped copy).
pub const DATA_ENV: &str = "GRAPHSPN_DATA";

/// The COLD maps shipped with the project: `data/cold-topomaps/` of the repository
/// (the folder holding `Freiburg/`, `Saarbrucken/`, `Stockholm/`).
pub fn shipped_data_dir() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest
        .parent()
        .unwrap_or(manifest)
        .join("data")
        .join("cold-topomaps")
}

/// The COLD data folder every command, test, bench and example reads: `arg` (a
/// `--data` flag) if given, else `$GRAPHSPN_DATA` if set and non-empty, else
/// [`shipped_data_dir`].
pub fn data_dir(arg: Option<&Path>) -> PathBuf {
    if let Some(a) = arg {
        return a.to_path_buf();
    }
    match std::env::var_os(DATA_ENV) {
        Some(v) if !v.is_empty() => PathBuf::from(v),
        _ => shipped_data_dir(),
    }
}

/// Room relabelled by the authors: `(from, to, new raw label)`, in building
/// [`ROOM_RELABEL_BUILDING`] only.
pub const ROOM_RELABEL: (&str, &str, &str) = ("7-2PO-1", "7-1PO-3", "1PO");

/// The building whose room [`ROOM_RELABEL`] the authors relabelled: a sequence folder
/// inside a folder of this name (another building's room of that id keeps its label).
pub const ROOM_RELABEL_BUILDING: &str = "Stockholm";

/// What a raw COLD label means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawLabel {
    /// One of the paper's ten classes (index into [`ClassSet::paper`]).
    Class(ClassId),
    /// `UN`: unknown; such nodes are dropped.
    Unknown,
}

/// The class of a raw COLD label (the table in `docs/FORMATS.md`), or `None`
/// for a label the table does not know.
pub fn raw_label_class(raw: &str) -> Option<RawLabel> {
    let c: ClassId = match raw {
        "DW" => 0,
        "CR" | "AT" | "ST" | "EV" => 1,
        "1PO" => 2,
        "2PO" | "PRO" => 3,
        "LO" | "MPO" => 4,
        "LAB" | "RL" | "LR" | "TR" => 5,
        "BA" => 6,
        "KT" => 7,
        "MR" | "LMR" | "CF" => 8,
        "UT" | "WS" | "PT" | "PA" => 9,
        "UN" => return Some(RawLabel::Unknown),
        _ => return None,
    };
    Some(RawLabel::Class(c))
}

struct RawNode {
    line: usize,
    placeholder: bool,
    x: f64,
    y: f64,
    label: RawLabel,
    raw_label: String,
    neighbors: Vec<i64>,
}

fn read(path: &Path) -> Result<String, MapError> {
    std::fs::read_to_string(path).map_err(|e| MapError::io(path, e))
}

fn parse_int(path: &Path, line: usize, column: usize, text: &str) -> Result<i64, MapError> {
    text.parse::<i64>().map_err(|_| MapError::BadNumber {
        path: path.to_path_buf(),
        line,
        column,
        text: text.to_string(),
        expected: "an integer",
    })
}

fn parse_float(path: &Path, line: usize, column: usize, text: &str) -> Result<f64, MapError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(MapError::BadNumber {
            path: path.to_path_buf(),
            line,
            column,
            text: text.to_string(),
            expected: "a finite number",
        }),
    }
}

/// Parses `nodes.dat` line by line; with more than `max_places` node lines, the rest
/// is only counted and the map refused ([`MapError::TooManyPlaces`]).
fn parse_nodes(path: &Path, max_places: usize) -> Result<BTreeMap<i64, RawNode>, MapError> {
    use std::io::BufRead;
    let file = std::fs::File::open(path).map_err(|e| MapError::io(path, e))?;
    let reader = std::io::BufReader::with_capacity(1 << 16, file);
    let mut nodes: BTreeMap<i64, RawNode> = BTreeMap::new();
    let mut count = 0usize;
    for (k, raw_line) in reader.lines().enumerate() {
        let raw_line = raw_line.map_err(|e| MapError::io(path, e))?;
        let line = k + 1;
        let cols: Vec<&str> = raw_line.split_whitespace().collect();
        if cols.is_empty() {
            continue;
        }
        count += 1;
        if count > max_places {
            continue;
        }
        if cols.len() != NODE_COLUMNS {
            return Err(MapError::ColumnCount {
                path: path.to_path_buf(),
                line,
                expected: NODE_COLUMNS,
                found: cols.len(),
            });
        }
        let id = parse_int(path, line, 0, cols[0])?;
        if PlaceId::try_from(id).is_err() {
            return Err(MapError::BadNodeId {
                path: path.to_path_buf(),
                line,
                id,
            });
        }
        let placeholder = match cols[1].parse::<i64>() {
            Ok(0) => false,
            Ok(1) => true,
            _ => {
                return Err(MapError::BadNumber {
                    path: path.to_path_buf(),
                    line,
                    column: 1,
                    text: cols[1].to_string(),
                    expected: "0 or 1 (the placeholder flag)",
                });
            }
        };
        let x = parse_float(path, line, 2, cols[2])?;
        let y = parse_float(path, line, 3, cols[3])?;
        for c in [4, 5, 6, 7, 9] {
            parse_float(path, line, c, cols[c])?;
        }
        let label = raw_label_class(cols[8]).ok_or_else(|| MapError::UnknownLabel {
            path: path.to_path_buf(),
            line,
            column: 8,
            label: cols[8].to_string(),
        })?;
        let mut neighbors = Vec::new();
        for t in 0..8 {
            let c = 10 + 3 * t;
            let nb = parse_int(path, line, c, cols[c])?;
            parse_float(path, line, c + 1, cols[c + 1])?;
            parse_int(path, line, c + 2, cols[c + 2])?;
            if nb != -1 {
                neighbors.push(nb);
            }
        }
        let node = RawNode {
            line,
            placeholder,
            x,
            y,
            label,
            raw_label: cols[8].to_string(),
            neighbors,
        };
        if let Some(first) = nodes.get(&id) {
            return Err(MapError::DuplicateNodeLine {
                path: path.to_path_buf(),
                line,
                first_line: first.line,
                id,
            });
        }
        nodes.insert(id, node);
    }
    if count > max_places {
        return Err(MapError::TooManyPlaces {
            path: path.to_path_buf(),
            places: count,
            limit: max_places,
        });
    }
    Ok(nodes)
}

/// Parse `rooms.dat`: node id → room id.
fn parse_rooms(path: &Path) -> Result<BTreeMap<i64, (usize, String)>, MapError> {
    let text = read(path)?;
    let mut rooms = BTreeMap::new();
    for (k, raw_line) in text.lines().enumerate() {
        let line = k + 1;
        let cols: Vec<&str> = raw_line.split_whitespace().collect();
        if cols.is_empty() {
            continue;
        }
        if cols.len() != 2 {
            return Err(MapError::ColumnCount {
                path: path.to_path_buf(),
                line,
                expected: 2,
                found: cols.len(),
            });
        }
        let id = parse_int(path, line, 0, cols[0])?;
        if room_label(cols[1]).is_none() {
            return Err(MapError::BadRoomId {
                path: path.to_path_buf(),
                line,
                room: cols[1].to_string(),
            });
        }
        if let Some((first_line, _)) = rooms.get(&id) {
            return Err(MapError::DuplicateNodeLine {
                path: path.to_path_buf(),
                line,
                first_line: *first_line,
                id,
            });
        }
        rooms.insert(id, (line, cols[1].to_string()));
    }
    Ok(rooms)
}

/// The LABEL part of a room id `floor-LABEL-k`.
fn room_label(room: &str) -> Option<&str> {
    let (_, rest) = room.split_once('-')?;
    let (label, _) = rest.rsplit_once('-')?;
    if label.is_empty() { None } else { Some(label) }
}

/// Nodes of a `nodes.dat` that the filtering dropped, by reason (ids ascending).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Dropped {
    /// Labelled `UN` (unknown).
    pub unknown: Vec<PlaceId>,
    /// Left without an edge once the `UN` nodes were gone.
    pub isolated: Vec<PlaceId>,
    /// Outside the largest connected component.
    pub disconnected: Vec<PlaceId>,
}

impl Dropped {
    /// Why place `id` was dropped, if it was.
    pub fn reason(&self, id: PlaceId) -> Option<&'static str> {
        if self.unknown.binary_search(&id).is_ok() {
            Some("it is labelled UN (unknown)")
        } else if self.isolated.binary_search(&id).is_ok() {
            Some("it has no edge to a labelled place")
        } else if self.disconnected.binary_search(&id).is_ok() {
            Some("it is not in the largest connected component")
        } else {
            None
        }
    }
}

/// Load one COLD sequence folder (holding `nodes.dat` and `rooms.dat`) with the
/// authors' filtering. The map is named `<parent folder>/<folder>`, e.g.
/// `Freiburg/seq1_cloudy1`. [`load_sequence_report`] also says what was dropped.
pub fn load_sequence(dir: impl AsRef<Path>) -> Result<TopoMap, MapError> {
    load_sequence_report(dir).map(|(m, _)| m)
}

/// [`load_sequence`], also returning the nodes the filtering dropped, so a caller can
/// warn about a disconnected map (whose smaller components are dropped) and explain
/// an evidence row for a dropped place.
pub fn load_sequence_report(dir: impl AsRef<Path>) -> Result<(TopoMap, Dropped), MapError> {
    load_sequence_limited(dir, usize::MAX)
}

/// [`load_sequence_report`] of a map of at most `max_places` places: a `nodes.dat`
/// listing more nodes is refused ([`MapError::TooManyPlaces`], with the count) while
/// it is read, before the map is built.
pub fn load_sequence_limited(
    dir: impl AsRef<Path>,
    max_places: usize,
) -> Result<(TopoMap, Dropped), MapError> {
    let dir = dir.as_ref();
    let nodes_path = dir.join("nodes.dat");
    let rooms_path = dir.join("rooms.dat");
    let nodes = parse_nodes(&nodes_path, max_places)?;
    let rooms = parse_rooms(&rooms_path)?;
    if let Some((&node, &(line, _))) = rooms.iter().find(|(id, _)| !nodes.contains_key(id)) {
        return Err(MapError::StrayRoom {
            path: rooms_path,
            line,
            node,
        });
    }

    // The building is the folder above the sequence, read as `sequence_name` reads it
    // (`.` and relative paths made absolute), however the path was written.
    let names = path_names(dir);
    let relabel_building = names.len() >= 2 && names[names.len() - 2] == ROOM_RELABEL_BUILDING;
    let mut classes_of: BTreeMap<i64, ClassId> = BTreeMap::new();
    for (&id, node) in &nodes {
        let (_, room) = rooms.get(&id).ok_or_else(|| MapError::MissingRoom {
            path: rooms_path.clone(),
            node: id,
            nodes_path: nodes_path.clone(),
            nodes_line: node.line,
        })?;
        if room_label(room) != Some(node.raw_label.as_str()) {
            return Err(MapError::RoomLabelMismatch {
                path: nodes_path.clone(),
                line: node.line,
                node: id,
                label: node.raw_label.clone(),
                room: room.clone(),
            });
        }
        let label = if relabel_building && room == ROOM_RELABEL.0 {
            raw_label_class(ROOM_RELABEL.2).unwrap_or(node.label)
        } else {
            node.label
        };
        if let RawLabel::Class(c) = label {
            classes_of.insert(id, c);
        }
        for &nb in &node.neighbors {
            if !nodes.contains_key(&nb) {
                return Err(MapError::MissingNeighbor {
                    path: nodes_path.clone(),
                    line: node.line,
                    node: id,
                    neighbor: nb,
                });
            }
        }
    }

    // Edges among kept (non-UN) nodes, both listing directions, de-duplicated.
    let mut edges: Vec<(PlaceId, PlaceId)> = Vec::new();
    let mut has_edge: BTreeMap<i64, bool> = BTreeMap::new();
    for (&id, node) in &nodes {
        if !classes_of.contains_key(&id) {
            continue;
        }
        for &nb in &node.neighbors {
            if nb != id && classes_of.contains_key(&nb) {
                edges.push((id as PlaceId, nb as PlaceId));
                has_edge.insert(id, true);
                has_edge.insert(nb, true);
            }
        }
    }
    let places: Vec<Place> = classes_of
        .iter()
        .filter(|(id, _)| has_edge.contains_key(id))
        .map(|(&id, &c)| {
            let n = &nodes[&id];
            Place {
                id: id as PlaceId,
                class: Some(c),
                placeholder: n.placeholder,
                x: n.x,
                y: n.y,
            }
        })
        .collect();
    if places.is_empty() {
        return Err(MapError::EmptyAfterFiltering {
            path: dir.to_path_buf(),
        });
    }
    let map = TopoMap::new(sequence_name(dir), ClassSet::paper(), places, edges)
        .map_err(|e| e.in_file(&nodes_path))?;
    let kept = map.largest_component();
    let kept_ids: std::collections::BTreeSet<PlaceId> = kept.places().map(|p| p.id).collect();
    let dropped = Dropped {
        unknown: nodes
            .keys()
            .filter(|id| !classes_of.contains_key(id))
            .map(|&id| id as PlaceId)
            .collect(),
        isolated: classes_of
            .keys()
            .filter(|id| !has_edge.contains_key(id))
            .map(|&id| id as PlaceId)
            .collect(),
        disconnected: map
            .places()
            .map(|p| p.id)
            .filter(|id| !kept_ids.contains(id))
            .collect(),
    };
    Ok((kept, dropped))
}

/// `building/sequence`: the folder's last two names, read from its absolute path
/// with `.` and `..` folded, so `--map .` and `--map ../seq` name the map as its
/// full path does.
fn sequence_name(dir: &Path) -> String {
    let names = path_names(dir);
    match names.as_slice() {
        [.., parent, leaf] => format!("{parent}/{leaf}"),
        [leaf] => leaf.clone(),
        [] => String::new(),
    }
}

/// The names along `path` made absolute (against the current folder), `.` dropped
/// and each `..` folding the name before it: what `path` names, without touching
/// the file system beyond the current folder.
pub(crate) fn path_names(path: &Path) -> Vec<String> {
    use std::path::Component;
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut names = Vec::new();
    for c in absolute.components() {
        match c {
            Component::Normal(n) => names.push(n.to_string_lossy().into_owned()),
            Component::ParentDir => {
                names.pop();
            }
            Component::CurDir | Component::RootDir | Component::Prefix(_) => {}
        }
    }
    names
}

/// Whether `path` names a hidden entry (`.name`), which folder scans skip.
pub(crate) fn is_hidden(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n.to_string_lossy().starts_with('.'))
}

/// Sequence folders of a building, sorted by name. Every sub-folder must be a
/// sequence (holding `nodes.dat`): one without is an error naming it
/// ([`MapError::NotASequence`]), not skipped; files and hidden entries (`.name`) are
/// not read.
pub fn sequence_dirs(building_dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, MapError> {
    let building_dir = building_dir.as_ref();
    let entries = std::fs::read_dir(building_dir).map_err(|e| MapError::io(building_dir, e))?;
    let mut dirs = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| MapError::io(building_dir, e))?;
        let p = entry.path();
        if is_hidden(&p) || !p.is_dir() {
            continue;
        }
        if !p.join("nodes.dat").is_file() {
            return Err(MapError::NotASequence { path: p });
        }
        dirs.push(p);
    }
    dirs.sort();
    if dirs.is_empty() {
        return Err(MapError::NoSequences {
            path: building_dir.to_path_buf(),
        });
    }
    Ok(dirs)
}

/// All sequences of one building (`data_dir/<building>/*`), sorted by sequence name.
pub fn load_building(data_dir: impl AsRef<Path>, building: &str) -> Result<Vec<TopoMap>, MapError> {
    Ok(load_building_report(data_dir, building)?
        .into_iter()
        .map(|(m, _)| m)
        .collect())
}

/// [`load_building`], with what the filtering dropped from each map.
pub fn load_building_report(
    data_dir: impl AsRef<Path>,
    building: &str,
) -> Result<Vec<(TopoMap, Dropped)>, MapError> {
    sequence_dirs(data_dir.as_ref().join(building))?
        .iter()
        .map(load_sequence_report)
        .collect()
}

/// The buildings of a data folder: its sub-folders (not hidden), sorted by name —
/// [`BUILDINGS`] for the shipped data. Each must be a building of sequences
/// ([`sequence_dirs`] says when one is not).
pub fn buildings_in(data_dir: impl AsRef<Path>) -> Result<Vec<String>, MapError> {
    let data_dir = data_dir.as_ref();
    let mut names = Vec::new();
    for entry in std::fs::read_dir(data_dir).map_err(|e| MapError::io(data_dir, e))? {
        let p = entry.map_err(|e| MapError::io(data_dir, e))?.path();
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if p.is_dir() && !is_hidden(&p) {
            names.push(name);
        }
    }
    names.sort();
    Ok(names)
}

/// All sequences of the three buildings, in [`BUILDINGS`] order, each building
/// sorted by sequence name (90 maps for the full data set).
pub fn load_all(data_dir: impl AsRef<Path>) -> Result<Vec<TopoMap>, MapError> {
    let mut all = Vec::new();
    for b in BUILDINGS {
        all.extend(load_building(data_dir.as_ref(), b)?);
    }
    Ok(all)
}
