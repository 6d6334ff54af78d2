//! The `axcomp` command-line tool: raw arguments are parsed by clap into [`cli::Cli`], each subcommand's
//! arguments are validated into a configuration by its module in [`commands`], which then does the work.

pub mod cli;
pub mod commands;

use clap::Parser;

/// Parses `args` and runs the chosen command.
pub fn run<I, T>(args: I) -> anyhow::Result<()>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match cli::Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) if e.use_stderr() => return Err(anyhow::anyhow!("{e}")),
        Err(e) => {
            // --help / --version: print and succeed.
            e.print()?;
            return Ok(());
        }
    };
    commands::dispatch(cli)
}
