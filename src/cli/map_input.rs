//! Where a command's maps come from: the data folder, COLD building names, `--map`
//! paths (a COLD sequence folder, a JSON map or a sequence name), reading them, and the
//! check that a map fits a model.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use graphspn_compiler::family::AnyModel;
use graphspn_compiler::map::cold::Dropped;
use graphspn_compiler::map::{TopoMap, cold};

use super::output::Outputs;

/// The COLD data folder: `--data`, else `$GRAPHSPN_DATA`, else the copy shipped in the
/// repository ([`cold::data_dir`]).
pub fn data_dir(arg: Option<PathBuf>) -> PathBuf {
    cold::data_dir(arg.as_deref())
}

/// The data folder ([`data_dir`]), or an error if it is not a folder.
pub fn require_data_dir(arg: Option<PathBuf>) -> Result<PathBuf> {
    let d = data_dir(arg);
    if !d.is_dir() {
        bail!(
            "--data {}: not a folder (a folder of buildings, each a folder of COLD sequences: the shipped COLD maps hold Freiburg/, Saarbrucken/, Stockholm/)",
            d.display()
        );
    }
    Ok(d)
}

/// Checks building names (known, no repeats) given with `flag`: COLD's three
/// ([`cold::BUILDINGS`]: the paper's protocol and its published figures need them).
pub fn check_buildings(flag: &str, buildings: &[String]) -> Result<()> {
    check_building_names(flag, buildings, &cold::BUILDINGS, "choose among")
}

/// Checks building names (no repeats) given with `flag` against the buildings of the
/// data folder `data` (its sub-folders: COLD's three, or a user's own).
pub fn check_data_buildings(flag: &str, buildings: &[String], data: &Path) -> Result<()> {
    let present = cold::buildings_in(data)?;
    let present: Vec<&str> = present.iter().map(String::as_str).collect();
    let known = format!("the data folder {} holds", data.display());
    check_building_names(flag, buildings, &present, &known)
}

/// Building names against `known`; `listed` introduces the list in the error.
fn check_building_names(
    flag: &str,
    buildings: &[String],
    known: &[&str],
    listed: &str,
) -> Result<()> {
    if buildings.is_empty() {
        bail!("{flag}: give at least one building");
    }
    for (i, b) in buildings.iter().enumerate() {
        if !known.contains(&b.as_str()) {
            bail!(
                "{flag}: unknown building {b:?}: {listed} {}",
                known.join(", ")
            );
        }
        if buildings[..i].contains(b) {
            bail!("{flag}: building {b} is listed twice (its maps would count twice)");
        }
    }
    Ok(())
}

/// All maps of the named buildings of the data folder, building by building in the
/// order given, each map that lost places to disconnection named in a warning
/// ([`warn_dropped`]). Names must have passed a building check.
pub fn load_buildings(data: &Path, buildings: &[String]) -> Result<Vec<TopoMap>> {
    let mut maps = Vec::new();
    for b in buildings {
        for (map, dropped) in cold::load_building_report(data, b)? {
            warn_dropped(&data.join(&map.name).display().to_string(), &map, &dropped);
            maps.push(map);
        }
    }
    Ok(maps)
}

/// The one warning about a loaded map that lost places to disconnection (the COLD
/// loader keeps the largest connected component, `docs/FORMATS.md`): on standard
/// error, naming the map's source, how many places were dropped and their ids. Places
/// labelled `UN` or left without an edge are dropped as the authors' filtering says,
/// without a warning (most COLD maps have some).
pub fn warn_dropped(source: &str, map: &TopoMap, dropped: &Dropped) {
    if !dropped.disconnected.is_empty() {
        eprintln!(
            "warning: {source}: the map is not connected; {} places outside its largest connected component were dropped (ids {}), {} are kept",
            dropped.disconnected.len(),
            id_list(&dropped.disconnected),
            map.num_places()
        );
    }
}

/// A loaded map and what the COLD filtering dropped from it (nothing for JSON maps).
pub struct LoadedMap {
    /// The map.
    pub map: TopoMap,
    /// Places the COLD loader dropped (empty for a JSON map).
    pub dropped: Dropped,
}

/// Where `--map` points: an existing path, else a sequence name under the data folder.
pub fn resolve_map(path: &Path, data: PathBuf) -> Result<PathBuf> {
    if path.exists() {
        return Ok(path.to_path_buf());
    }
    let under = data.join(path);
    if path.is_relative() && !path.as_os_str().is_empty() && under.exists() {
        return Ok(under);
    }
    bail!(
        "--map {}: no such map (give a COLD sequence folder, a JSON map, or a sequence name such as Freiburg/seq1_cloudy1 under the data folder {})",
        path.display(),
        data.display()
    )
}

/// Resolves `--map` ([`resolve_map`]) and declares it (and, for a COLD folder, its
/// two files) an input of `outputs`. Read it with [`read_map`] once every output is
/// declared.
pub fn declare_map(path: &Path, data: PathBuf, outputs: &mut Outputs) -> Result<PathBuf> {
    let resolved = resolve_map(path, data)?;
    outputs.input("--map", &resolved);
    if resolved.is_dir() {
        outputs.input("--map", &resolved.join("nodes.dat"));
        outputs.input("--map", &resolved.join("rooms.dat"));
    }
    Ok(resolved)
}

/// A map: a COLD sequence folder (nodes.dat + rooms.dat) or a JSON map file (a path
/// from [`declare_map`]). Warns on standard error when a COLD map loses places to
/// disconnection (the loader keeps the largest connected component).
pub fn read_map(resolved: &Path) -> Result<LoadedMap> {
    read_map_limited(resolved, usize::MAX)
}

/// [`read_map`] of a map of at most `max_places` places: a larger one is refused
/// while it is read ([`graphspn_compiler::map::MapError::TooManyPlaces`], with its
/// count), before its graph is built. [`super::budget::read_map_within`] turns that
/// into the message of the work that does not fit.
pub fn read_map_limited(resolved: &Path, max_places: usize) -> Result<LoadedMap> {
    let (map, dropped) = if resolved.is_dir() {
        cold::load_sequence_limited(resolved, max_places)?
    } else {
        (
            TopoMap::load_limited(resolved, max_places)?,
            Dropped::default(),
        )
    };
    warn_dropped(&resolved.display().to_string(), &map, &dropped);
    Ok(LoadedMap { map, dropped })
}

/// Up to 10 ids, comma-separated, then `…` if there are more.
pub fn id_list(ids: &[u32]) -> String {
    let mut s: Vec<String> = ids.iter().take(10).map(u32::to_string).collect();
    if ids.len() > 10 {
        s.push(format!("… ({} in all)", ids.len()));
    }
    s.join(", ")
}

/// The outcome of a family's map check (`graphspn_compiler::inputs::check_map`,
/// `graphspn_compiler::treemix::check_map`: the model's classes, at least one place)
/// as the command's error, naming both files. Every command that reads a map for a
/// model runs it right after reading the map.
pub fn map_fits<E>(checked: Result<(), E>, map: &Path, model: &Path) -> Result<()>
where
    E: std::error::Error + Send + Sync + 'static,
{
    checked.with_context(|| {
        format!(
            "--map {} does not fit --model {}",
            map.display(),
            model.display()
        )
    })
}

/// [`map_fits`] for a model of either family.
pub fn any_map_fits(
    model: &AnyModel,
    map: &TopoMap,
    map_path: &Path,
    model_path: &Path,
) -> Result<()> {
    match model {
        AnyModel::Graphspn(m) => map_fits(
            graphspn_compiler::inputs::check_map(m, map),
            map_path,
            model_path,
        ),
        AnyModel::TreeMixture(t) => map_fits(
            graphspn_compiler::treemix::check_map(t, map),
            map_path,
            model_path,
        ),
    }
}
