//! `axcomp`: thin entry point. Parsing lives in [`axcomp::cli`], the work in [`axcomp::commands`].

fn main() -> std::process::ExitCode {
    match axcomp::run(std::env::args_os()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            let code = axcomp::exit_code(&err);
            if code == axcomp::EXIT_GUARD_REFUSED {
                eprintln!("axcomp: refused: {err:#}");
            } else {
                eprintln!("axcomp: error: {err:#}");
            }
            std::process::ExitCode::from(code)
        }
    }
}
