//! The `axcomp` command-line tool: raw arguments are parsed by clap into [`commands::Cli`], each subcommand's
//! arguments are validated into a configuration by its module in [`commands`], which then does the work.

pub mod cli;
pub mod commands;
pub mod output;
pub mod provenance;

use clap::Parser;

/// Exit code for bad input: an unreadable or malformed file, a bad option, an output path that cannot be
/// written (then nothing is written), data that fails a `--strict` sanity check.
pub const EXIT_BAD_INPUT: u8 = 2;

/// Exit code when a do-no-harm guard refuses to write a model (its JSON and report are still written).
pub const EXIT_GUARD_REFUSED: u8 = 3;

/// Exit code when standard output was closed before the command finished writing to it (`axcomp … |
/// head`): the status a shell reports for a process ended by SIGPIPE (128 + 13), without a message. Output
/// files the command had not yet committed are not written (never half-written: [`output::OutputSet`]).
pub const EXIT_BROKEN_PIPE: u8 = 141;

/// True if a panic's payload is the standard library's `println!`/`print!` failing on a closed pipe
/// ("failed printing to stdout: Broken pipe (os error 32)"): what [`EXIT_BROKEN_PIPE`] stands for.
pub fn is_broken_pipe_panic(payload: &(dyn std::any::Any + Send)) -> bool {
    let text = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("");
    text.starts_with("failed printing to std") && text.contains("Broken pipe")
}

/// The exit codes as `--help` and the README state them.
pub const EXIT_CODES_HELP: &str = "\
Exit codes (every command):
  0  success
  2  bad input: unreadable or malformed data, a bad option, an output path that cannot be written
     (then no output file is written or changed), or a data warning under --strict
  3  refused by a guard: the model is not clearly better than no compensation; the JSON and report
     say why and are written, the model file is not (unless --force)
  141  standard output closed early (e.g. `| head`): stopped quietly; files not yet written are not
     written";

/// A command finished its analysis but refuses to write its result (e.g. the do-no-harm guard found the
/// model not clearly better than raw). Carries the process exit code; `main` maps it.
#[derive(Debug)]
pub struct Refused {
    /// Process exit code.
    pub code: u8,
    /// Why, for the user.
    pub reason: String,
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.reason)
    }
}

impl std::error::Error for Refused {}

/// The process exit code for an error returned by [`run`]: a [`Refused`] carries its own, anything else is
/// [`EXIT_BAD_INPUT`].
pub fn exit_code(err: &anyhow::Error) -> u8 {
    err.downcast_ref::<Refused>()
        .map_or(EXIT_BAD_INPUT, |r| r.code)
}

/// Parses `args` and runs the chosen command.
pub fn run<I, T>(args: I) -> anyhow::Result<()>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match commands::Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) if e.use_stderr() => {
            // clap renders "error: ..." itself; main adds the "axcomp: error:" prefix.
            let text = e.render().to_string();
            let text = text.trim_start_matches("error: ").trim_end().to_owned();
            return Err(anyhow::anyhow!(text));
        }
        Err(e) => {
            // --help / --version: print and succeed.
            e.print()?;
            return Ok(());
        }
    };
    commands::dispatch(cli)
}
