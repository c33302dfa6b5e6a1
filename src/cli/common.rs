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

/// Largest memory (bytes) a host command may plan to use before it refuses with an
/// estimate: 4 GiB.
pub const MEMORY_LIMIT: u128 = 4 << 30;

fn gb(bytes: u128) -> String {
    format!("{:.1} GB", bytes as f64 / 1e9)
}

fn load_model(model_path: &Path) -> Result<graphspn_compiler::learn::Model> {
    graphspn_compiler::learn::Model::load(model_path)
        .with_context(|| format!("loading model {}", model_path.display()))
}

fn instance_params(
    decompositions: usize,
    seed: u64,
) -> graphspn_compiler::instance::InstanceParams {
    graphspn_compiler::instance::InstanceParams {
        decompositions,
        candidates: decompositions.saturating_mul(3).max(15),
        seed,
    }
}

/// Loads a model and builds the explicit instance GraphSPN of `map` with
/// `decompositions` decompositions (best of 3×, at least 15 candidates) seeded by
/// `seed`. Refuses, before building, an instance estimated above [`MEMORY_LIMIT`].
pub fn instance_for(
    model_path: &Path,
    map: &TopoMap,
    decompositions: usize,
    seed: u64,
) -> Result<(
    graphspn_compiler::learn::Model,
    graphspn_compiler::instance::Instance,
)> {
    use graphspn_compiler::decompose::{DecompositionParams, decompose_best};
    use graphspn_compiler::instance::{Instance, estimated_explicit_bytes};
    let model = load_model(model_path)?;
    check_component_memory(&model, map, decompositions)?;
    let params = instance_params(decompositions, seed);
    let dp = DecompositionParams {
        count: params.decompositions,
        candidates: params.candidates,
        seed,
    };
    let decs = decompose_best(map, &model.templates, &dp)
        .with_context(|| format!("building the instance of map {:?}", map.name))?;
    // The SPN and its text (about as large again).
    let estimate = 2 * estimated_explicit_bytes(&model, &decs);
    if estimate > MEMORY_LIMIT {
        bail!(
            "the explicit instance SPN of map {:?} ({} places, --decompositions {decompositions}) would take about {} (limit {}): lower --decompositions or use a smaller map (`graphspn infer` answers queries without the explicit SPN)",
            map.name,
            map.num_places(),
            gb(estimate),
            gb(MEMORY_LIMIT)
        );
    }
    let inst = Instance::build(&model, map, decs)
        .with_context(|| format!("building the instance of map {:?}", map.name))?;
    Ok((model, inst))
}

/// Refuses `--decompositions` values whose component evaluator (and decomposition
/// step) is estimated above [`MEMORY_LIMIT`].
fn check_component_memory(
    model: &graphspn_compiler::learn::Model,
    map: &TopoMap,
    decompositions: usize,
) -> Result<()> {
    let p = instance_params(decompositions, 0);
    let estimate = graphspn_compiler::instance::estimated_component_bytes(
        map.num_places(),
        model.classes.len(),
        p.decompositions,
        p.candidates,
    );
    if estimate > MEMORY_LIMIT {
        bail!(
            "--decompositions {decompositions} on map {:?} ({} places) would take about {} (limit {}): lower --decompositions",
            map.name,
            map.num_places(),
            gb(estimate),
            gb(MEMORY_LIMIT)
        );
    }
    Ok(())
}

/// Loads a model and prepares the component-wise evaluator of `map`'s instance (same
/// decompositions as [`instance_for`], no explicit SPN: memory linear in places).
/// Refuses `--decompositions` estimated above [`MEMORY_LIMIT`] before decomposing.
pub fn component_instance_for(
    model_path: &Path,
    map: &TopoMap,
    decompositions: usize,
    seed: u64,
) -> Result<graphspn_compiler::instance::ComponentInstance> {
    let model = load_model(model_path)?;
    check_component_memory(&model, map, decompositions)?;
    graphspn_compiler::instance::ComponentInstance::for_map(
        &model,
        map,
        &instance_params(decompositions, seed),
    )
    .with_context(|| format!("building the instance of map {:?}", map.name))
}

/// Writes `text` to standard output; a closed pipe (e.g. `| head`) is not an error.
pub fn write_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => Ok(r.context("writing to standard output")?),
    }
}
