//! Sets of maps given as paths: a user's own building for `graphspn evaluate`.
//!
//! A path is one of
//! - a JSON map file (our format, `docs/FORMATS.md`): one map;
//! - a COLD sequence folder (holding `nodes.dat` and `rooms.dat`): one map;
//! - a folder holding JSON map files (`*.json`) and/or COLD sequence folders: every
//!   one of them, sorted by file name. Every sub-folder must be a COLD sequence (a
//!   folder without `nodes.dat` is an error naming it, not skipped); other files are
//!   not read, and [`load_map_set_report`] lists them so a caller can warn; hidden
//!   entries (`.name`) are skipped.

use std::path::{Path, PathBuf};

use super::cold::Dropped;
use super::{MapError, TopoMap, cold};

/// The maps a path holds (see the module docs), in a fixed order. Errors name the
/// path: missing, unreadable, a malformed map, a sub-folder that is not a COLD
/// sequence, two maps of the same name, or a folder with no map at all.
pub fn load_map_set(path: impl AsRef<Path>) -> Result<Vec<TopoMap>, MapError> {
    load_map_set_report(path).map(|r| r.maps)
}

/// What [`load_map_set_report`] read.
#[derive(Clone, Debug, Default)]
pub struct MapSetReport {
    /// The maps, in the set's order.
    pub maps: Vec<TopoMap>,
    /// What the COLD filtering dropped from each map (same order; nothing for a JSON
    /// map), so a caller can warn about a map that lost places.
    pub dropped: Vec<Dropped>,
    /// The files of the folder that were not read (not `*.json`, not hidden), sorted.
    pub not_read: Vec<PathBuf>,
}

/// [`load_map_set`], also returning what was dropped from each map and the files of
/// the folder that were not read.
pub fn load_map_set_report(path: impl AsRef<Path>) -> Result<MapSetReport, MapError> {
    let path = path.as_ref();
    if path.is_file() {
        return Ok(MapSetReport {
            maps: vec![TopoMap::load(path)?],
            dropped: vec![Dropped::default()],
            not_read: Vec::new(),
        });
    }
    if !path.is_dir() {
        return Err(MapError::MissingFile {
            path: path.to_path_buf(),
        });
    }
    if path.join("nodes.dat").is_file() {
        let (map, dropped) = cold::load_sequence_report(path)?;
        return Ok(MapSetReport {
            maps: vec![map],
            dropped: vec![dropped],
            not_read: Vec::new(),
        });
    }
    let mut entries: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(|e| MapError::io(path, e))?
        .map(|e| e.map(|e| e.path()).map_err(|e| MapError::io(path, e)))
        .collect::<Result<_, _>>()?;
    entries.sort();
    let mut maps: Vec<TopoMap> = Vec::new();
    let mut dropped: Vec<Dropped> = Vec::new();
    let mut sources: Vec<PathBuf> = Vec::new();
    let mut ignored = Vec::new();
    for p in entries {
        if cold::is_hidden(&p) {
            continue;
        }
        if p.is_dir() {
            if !p.join("nodes.dat").is_file() {
                return Err(MapError::NotASequence { path: p });
            }
            let (map, d) = cold::load_sequence_report(&p)?;
            maps.push(map);
            dropped.push(d);
        } else if p.extension().is_some_and(|x| x == "json") {
            maps.push(TopoMap::load(&p)?);
            dropped.push(Dropped::default());
        } else {
            ignored.push(p);
            continue;
        }
        let name = &maps[maps.len() - 1].name;
        if let Some(k) = maps[..maps.len() - 1].iter().position(|m| m.name == *name) {
            return Err(MapError::DuplicateMapName {
                name: name.clone(),
                first: sources[k].clone(),
                second: p,
            });
        }
        sources.push(p);
    }
    if maps.is_empty() {
        return Err(MapError::NoMaps {
            path: path.to_path_buf(),
        });
    }
    Ok(MapSetReport {
        maps,
        dropped,
        not_read: ignored,
    })
}

/// The name a map set is reported under: the file stem or the folder name (of the
/// absolute path, so `.` is named as the folder it is).
pub fn map_set_name(path: impl AsRef<Path>) -> String {
    let path = path.as_ref();
    let mut names = cold::path_names(path);
    if path.is_file()
        && let Some(stem) = path.file_stem()
        && let Some(last) = names.last_mut()
    {
        *last = stem.to_string_lossy().into_owned();
    }
    names
        .pop()
        .filter(|n| !n.is_empty())
        .unwrap_or_else(|| path.display().to_string())
}
