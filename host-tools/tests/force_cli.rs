//! `axcomp fit force` end to end on the real force data in `../shared` (skipped when absent, unless `CI` is
//! set): milling coefficients from the Kistler slotting files, the Kienzle law from the turning feed sweep and
//! its prediction of the depth sweep.

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
}

mod common;
use common::{read_json as json, scratch as tmp_dir, shared};

#[test]
fn milling_slotting_coefficients_are_plausible() {
    let Some(shared) = shared() else { return };
    let dir = tmp_dir("milling");
    let m = shared.join("data/real/force-milling-slot-kistler");
    let j = dir.join("m.json");
    let mut cmd = bin();
    cmd.args(["fit", "force", "--kind", "milling", "--dynoware"]);
    for f in [300, 600, 900, 1200, 1500] {
        cmd.arg(m.join(format!("6-n6000f{f}ap3ae25.csv")));
    }
    cmd.args([
        "--n-rpm",
        "6000",
        "--flutes",
        "2",
        "--ap-mm",
        "3",
        "--json",
        j.to_str().unwrap(),
        "--report",
    ]);
    cmd.arg(dir.join("report"));
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{}", String::from_utf8_lossy(&out.stdout));
    let v = json(&j);
    let c = &v["coefficients"];
    let val = |k: &str| c[k]["value"].as_f64().unwrap();
    let half = |k: &str| c[k]["ci95_half"].as_f64().unwrap();
    // Plausibility (not a reference value: the tool/material are undocumented): Ktc of order 10³ N/mm² for a
    // metal, Krc and Kac positive and smaller than Ktc, edge coefficients positive and of order 10 N/mm.
    assert!(
        (500.0..2500.0).contains(&val("ktc_n_mm2")),
        "Ktc {}",
        val("ktc_n_mm2")
    );
    assert!(val("krc_n_mm2") > 0.0 && val("krc_n_mm2") < val("ktc_n_mm2"));
    assert!(val("kac_n_mm2") > 0.0 && val("kac_n_mm2") < val("ktc_n_mm2"));
    for k in ["kte_n_mm", "kre_n_mm", "kae_n_mm"] {
        assert!((0.0..100.0).contains(&val(k)), "{k} {}", val(k));
    }
    // Intervals and residuals are reported; the Ktc interval is narrower than the value (well determined).
    assert!(half("ktc_n_mm2") > 0.0 && half("ktc_n_mm2") < val("ktc_n_mm2"));
    assert_eq!(c["residuals_n"].as_array().unwrap().len(), 5);
    // fz from the file names: 300 mm/min / (6000 rpm · 2) = 0.025 mm.
    assert!((v["tests"][0]["fz_mm"].as_f64().unwrap() - 0.025).abs() < 1e-12);
    assert_eq!(v["tests"][0]["revolutions"], 100);
    assert!(dir.join("report/report.md").is_file() && dir.join("report/mean_forces.svg").is_file());
}

#[test]
fn turning_kienzle_law_from_feed_sweep_predicts_depth_sweep() {
    let Some(shared) = shared() else { return };
    let dir = tmp_dir("turning");
    let t = shared.join("data/real/force-turning-kienzle");
    let j = dir.join("t.json");
    let out = bin()
        .args(["fit", "force", "--data"])
        .arg(t.join("Ks_feed_sweep_Datos_v5.csv"))
        .args([
            "--rename",
            "f_cal=fz_mm",
            "--rename",
            "Fz=Fz_N",
            "--set",
            "ap_mm=1",
            "--fix",
            "x_ap=1",
            "--fix",
            "z_n=0",
        ])
        .arg("--validate")
        .arg(t.join("fixed_feed_depth_sweep_Datos_v5.csv"))
        .args([
            "--validate-rename",
            "ap=ap_mm",
            "--json",
            j.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{}", String::from_utf8_lossy(&out.stdout));
    let v = json(&j);
    let mc = v["kienzle"]["mc"].as_f64().unwrap();
    let kc = v["kienzle"]["kc11_n_mm2"].as_f64().unwrap();
    // Plausible Kienzle exponent 0.1–0.3 (authors' Ks fit: m = 0.136 with KS0 = 1609.5 N/mm²).
    assert!((0.1..0.3).contains(&mc), "mc {mc}");
    assert!((1000.0..2500.0).contains(&kc), "kc1.1 {kc}");
    assert!(
        v["law"]["y_fz"]["ci95"].as_array().is_some(),
        "interval missing"
    );
    // The depth sweep (not used in the fit) is predicted within 20 % per point.
    let rel = v["validation"]["max_rel_error"].as_f64().unwrap();
    assert!(rel < 0.2, "depth sweep worst relative error {rel}");
}

#[test]
fn bad_inputs_are_named() {
    let dir = tmp_dir("bad");
    let f = dir.join("6-n6000f300ap3ae25.csv");
    std::fs::write(
        &f,
        "Sampling rate [Hz]:,10000\nTime,Fx,Fy,Fz\ns,N,N,N\n8,1,2,3\n8.0001,1,oops,3\n",
    )
    .unwrap();
    let out = bin()
        .args([
            "fit",
            "force",
            "--kind",
            "milling",
            "--n-rpm",
            "6000",
            "--flutes",
            "2",
            "--ap-mm",
            "3",
            "--dynoware",
        ])
        .args([&f, &f, &f])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("6-n6000f300ap3ae25.csv:5:3"),
        "{err}"
    );
    let out = bin()
        .args(["fit", "force", "--kind", "milling", "--dynoware"])
        .arg(&f)
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("--n-rpm"));
    let csv = dir.join("p.csv");
    std::fs::write(
        &csv,
        "ap_mm,fz_mm,force_N\n1,0.1,100\n1,0.2,180\n1,0.3,250\n",
    )
    .unwrap();
    let out = bin()
        .args(["fit", "force", "--data"])
        .arg(&csv)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--fix x_ap"), "{err}");
}
