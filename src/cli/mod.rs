//! Sub-commands of the `graphspn` tool that have grown beyond a few lines, one file each.

pub mod budget;
pub mod compile;
pub mod decompose;
pub mod evaluate;
pub mod evidence;
pub mod flag_checks;
pub mod generated_check;
pub mod infer;
pub mod instance;
pub mod map_input;
pub mod maps;
pub mod model_input;
pub mod output;
pub mod reproduce;
pub mod train;
