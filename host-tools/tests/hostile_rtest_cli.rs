/// `fit rtest --report r --out r/report.md`: before the fix the report's page overwrote the model (or
/// the reverse), exit 0. Now exit 2 naming the output and `--report`, nothing written.
#[test]
fn an_output_inside_the_report_folder_is_refused() {
    let dir = scratch("inside");
    rows_and_model(&dir);
    fails_untouched_naming(
        &[
            "fit",
            "rtest",
            "--data",
            "rt.csv",
            "--report",
            "r",
            "--out",
            "r/report.md",
        ],
        &dir,
        &["r/report.md", "--report"],
    );
}

/// `--out m.json --json fit.json` with m.json a link to fit.json: before the fix exit 0 and fit.json
/// held the model. Now exit 2 naming both.
#[cfg(unix)]
#[test]
fn two_outputs_that_are_one_file_through_a_link_are_refused() {
    let dir = scratch("link");
    rows_and_model(&dir);
    std::fs::write(dir.join("fit.json"), "{}\n").unwrap();
    std::os::unix::fs::symlink("fit.json", dir.join("m.json")).unwrap();
    fails_untouched_naming(
        &[
            "fit", "rtest", "--data", "rt.csv", "--out", "m.json", "--json", "fit.json",
        ],
        &dir,
        &["m.json", "fit.json", "same file"],
    );
}
