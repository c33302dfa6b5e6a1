//! Sets of maps given as paths: a user's own building for `graphspn evaluate`.
//!
//! A path is one of
//! - a JSON map file (our format, `docs/FORMATS.md`): one map;
//! - a COLD sequence folder (holding `nodes.dat` and `rooms.dat`): one map;
//! - a folder holding JSON map files (`*.json`) and/or COLD sequence folders: every
//!   one of them, sorted by file name (other files are ignored).

use std::path::{Path, PathBuf};

use super::{MapError, TopoMap, cold};

/// The maps a path holds (see the module docs), in a fixed order. Errors name the
/// path: missing, unreadable, a malformed map, or a folder with no map at all.
pub fn load_map_set(path: impl AsRef<Path>) -> Result<Vec<TopoMap>, MapError> {
    let path = path.as_ref();
    if path.is_file() {
        return Ok(vec![TopoMap::load(path)?]);
    }
    if !path.is_dir() {
        return Err(MapError::MissingFile {
            path: path.to_path_buf(),
        });
    }
    if path.join("nodes.dat").is_file() {
        return Ok(vec![cold::load_sequence(path)?]);
    }
    let mut entries: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(|e| MapError::io(path, e))?
        .map(|e| e.map(|e| e.path()).map_err(|e| MapError::io(path, e)))
        .collect::<Result<_, _>>()?;
    entries.sort();
    let mut maps = Vec::new();
    for p in entries {
        if p.is_dir() && p.join("nodes.dat").is_file() {
            maps.push(cold::load_sequence(&p)?);
        } else if p.is_file() && p.extension().is_some_and(|x| x == "json") {
            maps.push(TopoMap::load(&p)?);
        }
    }
    if maps.is_empty() {
        return Err(MapError::NoMaps {
            path: path.to_path_buf(),
        });
    }
    Ok(maps)
}

/// The name a map set is reported under: the file stem or the folder name.
pub fn map_set_name(path: impl AsRef<Path>) -> String {
    let path = path.as_ref();
    let name = if path.is_file() {
        path.file_stem()
    } else {
        path.file_name()
    };
    name.map(|n| n.to_string_lossy().into_owned())
        .filter(|n| !n.is_empty())
        .unwrap_or_else(|| path.display().to_string())
}
