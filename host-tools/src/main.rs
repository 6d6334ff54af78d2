//! `axcomp`: thin entry point. Parsing and the work live in [`axcomp::commands`].

use std::process::ExitCode;

fn main() -> ExitCode {
    // Standard output closed early (`axcomp … | head`): `println!` panics on the broken pipe (Rust
    // ignores SIGPIPE). Stop quietly with the status of a process ended by SIGPIPE, as other
    // command-line tools do, instead of a panic message and status 101.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !axcomp::is_broken_pipe_panic(info.payload()) {
            default_hook(info);
        }
    }));
    match std::panic::catch_unwind(|| axcomp::run(std::env::args_os())) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(err)) => {
            let code = axcomp::exit_code(&err);
            if code == axcomp::EXIT_GUARD_REFUSED {
                eprintln!("axcomp: refused: {err:#}");
            } else {
                eprintln!("axcomp: error: {err:#}");
            }
            ExitCode::from(code)
        }
        Err(payload) if axcomp::is_broken_pipe_panic(&*payload) => {
            ExitCode::from(axcomp::EXIT_BROKEN_PIPE)
        }
        Err(payload) => std::panic::resume_unwind(payload),
    }
}
