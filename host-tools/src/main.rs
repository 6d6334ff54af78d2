//! `axcomp`: thin entry point. Parsing lives in [`axcomp::cli`], the work in [`axcomp::commands`].

fn main() -> std::process::ExitCode {
    match axcomp::run(std::env::args_os()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("axcomp: error: {err:#}");
            std::process::ExitCode::from(2)
        }
    }
}
