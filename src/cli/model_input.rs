//! What a command builds on a map from `--model`: reading the model file, the
//! decompositions (from a file or drawn) and the instance evaluators, each refused
//! with the flag to change when it would not fit in memory.

use std::path::Path;

use anyhow::{Context, Result, bail};
use graphspn_compiler::decompose::{Decomposition, DecompositionStrategy};
use graphspn_compiler::family::AnyModel;
use graphspn_compiler::instance::{Instance, InstanceParams};
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::TopoMap;

use super::budget::{MEMORY_LIMIT, gb};
use super::output::check_input_file;

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

/// Largest `--decompositions` accepted by `infer`, `instance`, `compile` and `decompose`.
pub const MAX_DECOMPOSITIONS: usize = graphspn_compiler::decompose::MAX_DECOMPOSITIONS;

/// How many decompositions the decompositions file `path` (given with `flag`) holds,
/// counted as it is read without keeping them; refused when it is missing or a folder
/// ([`check_input_file`]), or holds none or more than [`MAX_DECOMPOSITIONS`]. Commands
/// declare the file with `Outputs::input` and leave its checks to this, so a flag that
/// does not apply to the model's family is refused as such first.
pub fn count_decompositions_file(flag: &str, path: &Path) -> Result<usize> {
    check_input_file(flag, path)?;
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
