//! Helpers shared by several sub-commands.

use std::path::{Path, PathBuf};

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

/// A map: a COLD sequence folder (nodes.dat + rooms.dat), a JSON map file, or a
/// sequence name such as `Freiburg/seq1_cloudy1` under the data folder.
pub fn load_map(path: &Path, data: Option<PathBuf>) -> Result<TopoMap> {
    let resolved = if path.exists() {
        path.to_path_buf()
    } else if let Some(d) = data.filter(|_| path.is_relative()) {
        d.join(path)
    } else {
        path.to_path_buf()
    };
    if resolved.is_dir() {
        Ok(cold::load_sequence(&resolved)
            .with_context(|| format!("loading COLD sequence {}", resolved.display()))?)
    } else if resolved.exists() {
        Ok(TopoMap::load(&resolved)
            .with_context(|| format!("loading JSON map {}", resolved.display()))?)
    } else {
        bail!(
            "{}: no such map (give a COLD sequence folder, a JSON map, or a sequence name under --data / $GRAPHSPN_DATA)",
            path.display()
        )
    }
}

/// Loads a model and builds the instance GraphSPN of `map` with `decompositions`
/// decompositions (best of 3×, at least 15 candidates) seeded by `seed`.
pub fn instance_for(
    model_path: &Path,
    map: &TopoMap,
    decompositions: usize,
    seed: u64,
) -> Result<(
    graphspn_compiler::learn::Model,
    graphspn_compiler::instance::Instance,
)> {
    use graphspn_compiler::instance::{Instance, InstanceParams};
    let model = graphspn_compiler::learn::Model::load(model_path)
        .with_context(|| format!("loading model {}", model_path.display()))?;
    let params = InstanceParams {
        decompositions,
        candidates: (3 * decompositions).max(15),
        seed,
    };
    let inst = Instance::for_map(&model, map, &params)
        .with_context(|| format!("building the instance of map {:?}", map.name))?;
    Ok((model, inst))
}

/// Writes `text` to standard output; a closed pipe (e.g. `| head`) is not an error.
pub fn write_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => Ok(r.context("writing to standard output")?),
    }
}
