//! Helpers shared by several sub-commands.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use graphspn_compiler::map::{TopoMap, cold};

/// The data folder: the argument, else `$GRAPHSPN_DATA`.
pub fn data_dir(arg: Option<PathBuf>) -> Option<PathBuf> {
    arg.or_else(|| std::env::var_os("GRAPHSPN_DATA").map(PathBuf::from))
}

/// The data folder, or an error saying how to give one.
pub fn require_data_dir(arg: Option<PathBuf>) -> Result<PathBuf> {
    match data_dir(arg) {
        Some(d) => Ok(d),
        None => bail!("no data folder: pass --data DIR or set GRAPHSPN_DATA"),
    }
}

/// All maps of the named COLD buildings, building by building in the order given.
pub fn load_buildings(data: &std::path::Path, buildings: &[String]) -> Result<Vec<TopoMap>> {
    let mut maps = Vec::new();
    for b in buildings {
        if !cold::BUILDINGS.contains(&b.as_str()) {
            bail!(
                "unknown building {b:?}: choose among {}",
                cold::BUILDINGS.join(", ")
            );
        }
        maps.extend(
            cold::load_building(data, b)
                .with_context(|| format!("loading building {b} from {}", data.display()))?,
        );
    }
    Ok(maps)
}
