//! The README's copy-paste chains, run as written, so the README cannot go stale.
//!
//! Glossary: a *chain* is a fenced ```` ```sh ```` block of `README.md` whose first line is
//! `# chain: NAME`; its `# writes: F1 F2 DIR/ ...` line names the files (and folders, ending in `/`) the
//! chain must leave behind. Every chain runs in a fresh scratch folder under `bash -euo pipefail` with the
//! tested `axcomp` binary first on `PATH`; it must exit 0 and write every named file, non-empty. A chain
//! reading real data reads it from `$R` (the README has the user set it to `../shared/data/real`); the test
//! sets `R` to the real-data folder of the shared folder the other CLI tests use, and skips those chains
//! when it is absent (a failure under `CI`).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use common::{scratch, shared};

/// One `# chain:` block of the README.
#[derive(Debug)]
struct Chain {
    name: String,
    /// 1-based line of the block's opening fence, for messages.
    line: usize,
    script: String,
    writes: Vec<String>,
}

fn readme() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Every ```` ```sh ```` block whose first line is `# chain: NAME`, in README order.
fn chains(text: &str) -> Vec<Chain> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        if lines[i].trim_end() != "```sh" {
            i += 1;
            continue;
        }
        let start = i;
        let end = (i + 1..lines.len())
            .find(|&k| lines[k].trim_end() == "```")
            .unwrap_or_else(|| panic!("README.md:{}: ```sh block never closed", start + 1));
        let body = &lines[start + 1..end];
        if let Some(name) = body.first().and_then(|l| l.strip_prefix("# chain:")) {
            let writes = body
                .iter()
                .filter_map(|l| l.strip_prefix("# writes:"))
                .flat_map(|w| w.split_whitespace().map(str::to_string))
                .collect();
            out.push(Chain {
                name: name.trim().to_string(),
                line: start + 1,
                script: body.join("\n"),
                writes,
            });
        }
        i = end + 1;
    }
    out
}

/// Whether a chain reads real data (`$R/...`).
fn reads_real_data(chain: &Chain) -> bool {
    chain.script.contains("$R/")
}

/// The folder holding the tested binary, to put first on `PATH`.
fn bin_dir() -> PathBuf {
    Path::new(env!("CARGO_BIN_EXE_axcomp"))
        .parent()
        .expect("the binary's folder")
        .to_path_buf()
}

/// Runs one chain in a scratch folder; panics with the chain's output when it fails or misses a file.
fn run_chain(chain: &Chain, real_data: Option<&Path>) {
    let dir = scratch(&chain.name);
    let path = format!(
        "{}:{}",
        bin_dir().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let t0 = Instant::now();
    let mut cmd = Command::new("bash");
    cmd.args(["-euo", "pipefail", "-c", &chain.script])
        .current_dir(&*dir)
        .env("PATH", path)
        .env_remove("R");
    if let Some(r) = real_data {
        cmd.env("R", r);
    }
    let out = cmd.output().expect("bash runs");
    let secs = t0.elapsed().as_secs_f64();
    assert!(
        out.status.success(),
        "README.md:{} chain `{}` exited {:?}\n--- stdout\n{}\n--- stderr\n{}",
        chain.line,
        chain.name,
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    for w in &chain.writes {
        let p = dir.join(w);
        let ok = if w.ends_with('/') {
            p.is_dir() && std::fs::read_dir(&p).map_or(false, |mut d| d.next().is_some())
        } else {
            std::fs::metadata(&p).map_or(false, |m| m.is_file() && m.len() > 0)
        };
        assert!(
            ok,
            "README.md:{} chain `{}`: `{w}` is not written (or empty)",
            chain.line, chain.name
        );
    }
    println!("chain `{}`: ok in {secs:.1} s", chain.name);
}

/// The README holds one chain for each of the five systems, each naming what it writes.
#[test]
fn readme_has_a_chain_per_system() {
    let text = readme();
    let found = chains(&text);
    for system in ["positioning", "thermal", "geometry", "rotary", "probe"] {
        assert!(
            found.iter().any(|c| c.name == system),
            "README.md has no `# chain: {system}` block (found: {:?})",
            found.iter().map(|c| &c.name).collect::<Vec<_>>()
        );
    }
    for c in &found {
        assert!(
            !c.writes.is_empty(),
            "README.md:{} chain `{}` has no `# writes:` line",
            c.line,
            c.name
        );
    }
}

/// Every chain on the twin runs as written and writes what it says.
#[test]
fn twin_chains_run_as_written() {
    let text = readme();
    let twin: Vec<Chain> = chains(&text)
        .into_iter()
        .filter(|c| !reads_real_data(c))
        .collect();
    assert!(!twin.is_empty());
    for c in &twin {
        run_chain(c, None);
    }
}

/// Every chain on real data (`$R`, the shared folder's `data/real`) runs as written and writes what it says.
#[test]
fn real_data_chains_run_as_written() {
    let text = readme();
    let real: Vec<Chain> = chains(&text)
        .into_iter()
        .filter(|c| reads_real_data(c))
        .collect();
    assert!(!real.is_empty(), "the README has no chain on real data");
    let Some(s) = shared() else { return };
    let real_data = s.join("data/real");
    for c in &real {
        run_chain(c, Some(&real_data));
    }
}

/// The README's exit-code table lists exactly the codes `axcomp --help` states (`axcomp::EXIT_CODES_HELP`).
#[test]
fn readme_exit_codes_match_the_help() {
    let text = readme();
    let section = text
        .split("## Exit codes")
        .nth(1)
        .expect("README.md has an `## Exit codes` section");
    let section = section.split("\n## ").next().unwrap_or(section);
    let in_readme: Vec<u32> = section
        .lines()
        .filter_map(|l| l.strip_prefix("| "))
        .filter_map(|l| l.split(" |").next()?.trim().parse().ok())
        .collect();
    let in_help: Vec<u32> = axcomp::EXIT_CODES_HELP
        .lines()
        .filter_map(|l| l.split_whitespace().next()?.parse().ok())
        .collect();
    assert_eq!(in_readme, in_help, "README exit codes vs axcomp --help");
    assert_eq!(in_help, [0, 2, 3, 141]);
}
