//! Helpers shared by several sub-commands.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use graphspn_compiler::decompose::{Decomposition, DecompositionStrategy};
use graphspn_compiler::domain::{self, DomainError};
use graphspn_compiler::family::AnyModel;
use graphspn_compiler::instance::{Instance, InstanceParams};
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::cold::Dropped;
use graphspn_compiler::map::{TopoMap, cold};

use super::budget::{MEMORY_LIMIT, gb};
use super::output::{Outputs, check_input_file};

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
            "--data {}: not a folder (the COLD maps folder holding Freiburg/, Saarbrucken/, Stockholm/)",
            d.display()
        );
    }
    Ok(d)
}

/// Checks building names (known, no repeats) given with `flag`.
pub fn check_buildings(flag: &str, buildings: &[String]) -> Result<()> {
    if buildings.is_empty() {
        bail!("{flag}: give at least one building");
    }
    for (i, b) in buildings.iter().enumerate() {
        if !cold::BUILDINGS.contains(&b.as_str()) {
            bail!(
                "{flag}: unknown building {b:?}: choose among {}",
                cold::BUILDINGS.join(", ")
            );
        }
        if buildings[..i].contains(b) {
            bail!("{flag}: building {b} is listed twice (its maps would count twice)");
        }
    }
    Ok(())
}

/// All maps of the named COLD buildings, building by building in the order given.
/// Names must have passed [`check_buildings`].
pub fn load_buildings(data: &Path, buildings: &[String]) -> Result<Vec<TopoMap>> {
    let mut maps = Vec::new();
    for b in buildings {
        maps.extend(cold::load_building(data, b)?);
    }
    Ok(maps)
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
    if !dropped.disconnected.is_empty() {
        let total = map.num_places() + dropped.disconnected.len();
        eprintln!(
            "warning: {}: the map is not connected; {} of its {total} places are outside the largest connected component and were dropped (ids {})",
            resolved.display(),
            dropped.disconnected.len(),
            id_list(&dropped.disconnected)
        );
    }
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

/// Reads a model (validated by [`Model::load`]; errors name the file, template and node).
pub fn load_model(path: &Path) -> Result<Model> {
    check_input_file("--model", path)?;
    Ok(Model::load(path)?)
}

/// Reads a model file of either family (`--model`).
pub fn load_any_model(path: &Path) -> Result<AnyModel> {
    check_input_file("--model", path)?;
    Ok(AnyModel::load(path)?)
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

/// Checks a number of decompositions given with `flag` before any work, against its
/// domain ([`graphspn_compiler::domain::decompositions`]).
pub fn check_decomposition_count(flag: &str, count: usize) -> Result<()> {
    domain::decompositions("count", count).map_err(|e| {
        anyhow::anyhow!(
            "{flag} {}: {} (each decomposition adds a copy of the map's template networks)",
            e.value,
            e.domain
        )
    })
}

/// Refuses the GraphSPN-only flags that were given (`(flag, given)`) for a model that
/// holds a tree mixture.
pub fn refuse_graphspn_flags(flags: &[(&str, bool)]) -> Result<()> {
    if let Some((flag, _)) = flags.iter().find(|f| f.1) {
        bail!("{flag} applies to GraphSPN models; --model holds a tree mixture");
    }
    Ok(())
}

/// A flag's value checked by a [`graphspn_compiler::domain`] function, as the flag's
/// error: `--flag value: must be …`.
pub fn flag_domain(flag: &str, checked: Result<(), DomainError>) -> Result<()> {
    checked.map_err(|e| anyhow::anyhow!("{flag} {}: {}", e.value, e.domain))
}

/// How many decompositions the decompositions file `path` (given with `flag`) holds,
/// counted as it is read without keeping them; refused when none or more than
/// [`MAX_DECOMPOSITIONS`].
pub fn count_decompositions_file(flag: &str, path: &Path) -> Result<usize> {
    let count = graphspn_compiler::decompose::file::count(path)
        .with_context(|| format!("{flag} {}", path.display()))?;
    if count == 0 {
        bail!("{flag} {}: holds no decompositions", path.display());
    }
    if count > MAX_DECOMPOSITIONS {
        bail!(
            "{flag} {}: holds {count} decompositions, at most {MAX_DECOMPOSITIONS} are accepted",
            path.display()
        );
    }
    Ok(count)
}

/// A setting outside its domain ([`graphspn_compiler::domain`]) as the error of the
/// flag that gave it: `flags` maps setting paths to flags; a setting without a flag
/// keeps its path.
pub fn flag_error(e: DomainError, flags: &[(&str, &str)]) -> anyhow::Error {
    match flags.iter().find(|(setting, _)| *setting == e.setting) {
        Some((_, flag)) => anyhow::anyhow!("{flag} {}: {}", e.value, e.domain),
        None => anyhow::anyhow!("{e}"),
    }
}

/// Parses `--strategy` (`paper` or `cover`).
pub fn parse_strategy(s: &str) -> Result<DecompositionStrategy, String> {
    DecompositionStrategy::from_name(s)
        .ok_or_else(|| format!("unknown decomposition strategy {s:?}: give paper or cover"))
}

/// Largest `--decompositions` accepted by `infer`, `instance`, `compile` and `decompose`.
pub const MAX_DECOMPOSITIONS: usize = graphspn_compiler::decompose::MAX_DECOMPOSITIONS;

/// Decompositions for `map`: read from `file` (a decompositions file, checked against
/// the map and the model's templates) or made by the seeded decomposer.
pub fn decompositions_for(
    model: &Model,
    map: &TopoMap,
    file: Option<&Path>,
    count: usize,
    seed: u64,
    strategy: DecompositionStrategy,
) -> Result<Vec<Decomposition>> {
    match file {
        Some(f) => {
            let decs = graphspn_compiler::decompose::file::load(f, map, &model.templates)?;
            if decs.is_empty() {
                bail!("{}: holds no decompositions", f.display());
            }
            Ok(decs)
        }
        None => {
            let params = InstanceParams {
                decompositions: count,
                candidates: super::budget::candidates(count),
                seed,
                strategy,
            };
            Ok(params.decompose(model, map)?)
        }
    }
}

/// Builds the explicit instance GraphSPN of `map` from `decompositions`; refuses,
/// before building, one estimated above [`MEMORY_LIMIT`] (the SPN and its text).
pub fn instance_of(
    model: &Model,
    map: &TopoMap,
    decompositions: Vec<Decomposition>,
) -> Result<Instance> {
    // The SPN, and its text, which is built whole before it is written: measured at
    // 2.3-2.5 times the SPN's estimate in JSON (peak 6.9 GB where the SPN alone was
    // estimated at 2.1 GB, 1,000 places and 44 decompositions), so four times it.
    let estimate =
        4 * graphspn_compiler::instance::estimated_explicit_bytes(model, &decompositions);
    if estimate > MEMORY_LIMIT {
        bail!(
            "the explicit instance SPN of map {:?} ({} places, {} decompositions) would take about {} with its text (limit {}): use fewer decompositions (--decompositions, or a smaller --decompositions-file) or a smaller map (`graphspn infer` answers queries without the explicit SPN)",
            map.name,
            map.num_places(),
            decompositions.len(),
            gb(estimate),
            gb(MEMORY_LIMIT)
        );
    }
    Instance::build(model, map, decompositions)
        .with_context(|| format!("building the instance of map {:?}", map.name))
}

/// The component-wise evaluator of `map`'s instance mixing `decompositions` (no
/// explicit SPN: memory linear in places).
pub fn component_instance_of(
    model: &Model,
    map: &TopoMap,
    decompositions: Vec<Decomposition>,
) -> Result<graphspn_compiler::instance::ComponentInstance> {
    graphspn_compiler::instance::ComponentInstance::build(model, map, decompositions)
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

/// An error and its causes on one line, each cause once: a cause whose text the
/// line already holds (library errors repeat their source in their message) is
/// skipped.
pub fn error_chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let msg = cause.to_string();
        if line.contains(&msg) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&msg);
    }
    line
}
