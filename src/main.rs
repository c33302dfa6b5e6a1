//! The `graphspn` command-line tool.

use anyhow::Result;
use clap::{Parser, Subcommand};

/// GraphSPN semantic maps: learn, infer, compile.
#[derive(Parser)]
#[command(name = "graphspn", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the statistics of the COLD maps in a data folder.
    Stats {
        /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA).
        #[arg(long)]
        data: Option<std::path::PathBuf>,
    },
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Stats { data } => {
            let _ = data;
            anyhow::bail!("not implemented yet")
        }
    }
}
