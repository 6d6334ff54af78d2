//! Argument types shared by several commands (the contract is `../shared/spec/interfaces.md`). The
//! subcommand tree that names each command's own arguments is [`crate::commands::Cli`]; this module names
//! no command, so every command may import it.

/// Options shared by every command that reads a measurement CSV (see the contract's "Common options").
#[derive(Debug, Clone, clap::Args)]
pub struct DataArgs {
    /// The measurement CSV.
    #[arg(long, value_name = "FILE")]
    pub data: std::path::PathBuf,
    /// Keep only rows where COL equals VALUE (repeatable).
    #[arg(long = "where", value_name = "COL=VALUE")]
    pub where_: Vec<String>,
    /// Rename a column before anything else (repeatable).
    #[arg(long, value_name = "OLD=NEW")]
    pub rename: Vec<String>,
    /// Multiply a column after renaming (repeatable).
    #[arg(long, value_name = "COL=FACTOR")]
    pub scale: Vec<String>,
}
