//! Checks of command-line flags against their domains, with errors that name the flag.

use anyhow::{Result, bail};
use graphspn_compiler::decompose::DecompositionStrategy;
use graphspn_compiler::domain::{self, DomainError};

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

/// Refuses `--trees` for a GraphSPN model; checks it against its domain (1 to 64)
/// when given.
pub fn check_trees_flag(trees: Option<usize>, graphspn: bool) -> Result<()> {
    match trees {
        Some(_) if graphspn => {
            bail!("--trees applies to tree-mixture models; --model holds a GraphSPN")
        }
        Some(t) => flag_domain("--trees", domain::trees("trees", t)),
        None => Ok(()),
    }
}

/// A flag's value checked by a [`graphspn_compiler::domain`] function, as the flag's
/// error: `--flag value: must be …`.
pub fn flag_domain(flag: &str, checked: Result<(), DomainError>) -> Result<()> {
    checked.map_err(|e| anyhow::anyhow!("{flag} {}: {}", e.value, e.domain))
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
