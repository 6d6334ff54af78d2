//! `axcomp diagnose` on laser-line data (twin lines from `axcomp plan geometry --simulate`): the withheld
//! squareness is named, a complete model is `none`, bad `--model` names and empty holdouts are named errors
//! with nothing written.

mod common;
use common::{axcomp_in, fails_untouched, ok_in, read_json, scratch};

#[test]
fn names_withheld_squareness_and_says_none_for_the_complete_model() {
    let dir = scratch("lines");
    ok_in(
        &[
            "plan",
            "geometry",
            "--stroke",
            "600,500,400",
            "--twin-plan",
            "complete",
            "--simulate",
            "lines.csv",
            "--seed",
            "3",
        ],
        &dir,
    );
    // The model without the three squareness constants; held out: the X line at y = 500 (reads −y·EC0Y)
    // and the Z line at x = 600 (reads nothing of them), chosen so the rest determines the model.
    let without_squareness =
        "EXX,EYX,EZX,EAX,EBX,ECX,EXY,EYY,EZY,EAY,EBY,ECY,EXZ,EYZ,EZZ,EAZ,EBZ,ECZ";
    let o = axcomp_in(
        &[
            "diagnose",
            "--data",
            "lines.csv",
            "--model",
            without_squareness,
            "--holdout",
            "line=X2,Z2",
            "--json",
            "d.json",
            "--report",
            "rep",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = read_json(&dir.join("d.json"));
    assert_eq!(d["verdict"], "squareness", "{}", d["note"]);
    // Contract fields, and the squareness shrinks the held-out gap most (measured: 1.997 → 1.283 µm,
    // 35.8 %, σ = 1 µm; required ≥ 20 %, four times the verdict rule's 5 % floor).
    assert!(d["gap"]["holdout_rms_um"].as_f64().unwrap() > 0.0);
    let e0 = &d["effects"][0];
    assert_eq!(e0["kind"], "squareness");
    assert!(e0["shrink_pct"].as_f64().unwrap() >= 20.0, "{e0}");
    assert!(
        e0["holdout_rms_after_um"].is_number()
            && e0["params"].is_object()
            && e0["score"].is_number()
    );
    assert!(d["where"].is_array());
    assert_eq!(d["holdout_lines"].as_array().unwrap().len(), 2);
    assert!(dir.join("rep/diagnosis.md").exists());
    let na = d["not_applicable"].as_array().unwrap();
    assert!(
        na.iter()
            .any(|s| s.as_str().unwrap().starts_with("abbe_angular")),
        "{na:?}"
    );
    // The complete model: nothing beyond noise on the same held-out lines.
    ok_in(
        &[
            "diagnose",
            "--data",
            "lines.csv",
            "--model",
            "geometry",
            "--holdout",
            "line=X2,Z2",
            "--json",
            "full.json",
        ],
        &dir,
    );
    let d = read_json(&dir.join("full.json"));
    assert_eq!(d["verdict"], "none", "{}", d["note"]);
}

#[test]
fn bad_line_input_is_named_and_writes_nothing() {
    let dir = scratch("lines-bad");
    ok_in(
        &[
            "plan",
            "geometry",
            "--stroke",
            "600,500,400",
            "--twin-plan",
            "complete",
            "--simulate",
            "lines.csv",
        ],
        &dir,
    );
    fails_untouched(
        &[
            "diagnose",
            "--data",
            "lines.csv",
            "--model",
            "EXX,EQQ",
            "--holdout",
            "line=X2",
            "--json",
            "d.json",
        ],
        &dir,
        "EQQ",
    );
    fails_untouched(
        &[
            "diagnose",
            "--data",
            "lines.csv",
            "--model",
            "geometry",
            "--holdout",
            "line=nope",
            "--json",
            "d.json",
        ],
        &dir,
        "holdout",
    );
}
