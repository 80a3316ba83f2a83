//! `phyllo timeline`: plots against degree-days.

use crate::common::{ok, phyllo};
use crate::two_genotypes;

/// `phyllo timeline --plot/--plots --degree-days`: the x axis in degree-days
/// of the imported temperature log; refused, with the reason, without a log,
/// without a plot to draw, and for a plant whose sessions the log does not
/// cover.
#[test]
fn timelines_plot_against_degree_days() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = two_genotypes(d);
    let cfg = cfg.as_str();
    let png = d.join("F-1.png");
    let png_arg = png.to_str().unwrap();
    let out = phyllo(&["timeline", "-c", cfg, "F-1", "--plot", png_arg, "--degree-days"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("has no temperature log"),
        "{err}"
    );
    let out = phyllo(&["timeline", "-c", cfg, "F-1", "--degree-days"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("give --plot"), "{err}");

    // Hourly from 1 to 15 November only: the last week of sessions is outside it.
    let mut log = String::from("timestamp,temp_c\n");
    for h in 0..(15 * 24) {
        log += &format!("2026-11-{:02}T{:02}:00:00,22\n", 1 + h / 24, h % 24);
    }
    std::fs::write(d.join("log.csv"), &log).unwrap();
    ok(&["import", "-c", cfg, d.join("log.csv").to_str().unwrap()]);
    let out = phyllo(&["timeline", "-c", cfg, "F-1", "--plot", png_arg, "--degree-days"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("plant F-1: the temperature log does not cover"),
        "{err}"
    );
    assert!(!png.exists(), "no half-drawn plot is left");
    // The nightly plots in degree-days: the plants the log does not cover are drawn in days.
    let mut text = std::fs::read_to_string(cfg).unwrap();
    text += "[export]\nplot_axis = \"degree-days\"\n";
    std::fs::write(cfg, text).unwrap();
    let out = ok(&["export", "-c", cfg]);
    assert!(
        out.contains("plots: 6 plants in days, their sessions outside the temperature log"),
        "{out}"
    );
    assert_eq!(
        std::fs::read_dir(d.join("state/exports/plots")).unwrap().count(),
        6
    );

    // The log runs on to the end of November: every session is covered.
    let mut rest = String::from("timestamp,temp_c\n");
    for h in (15 * 24)..(30 * 24) {
        rest += &format!("2026-11-{:02}T{:02}:00:00,22\n", 1 + h / 24, h % 24);
    }
    std::fs::write(d.join("rest.csv"), &rest).unwrap();
    ok(&["import", "-c", cfg, d.join("rest.csv").to_str().unwrap()]);
    ok(&["timeline", "-c", cfg, "F-1", "--plot", png_arg, "--degree-days"]);
    let out = ok(&["export", "-c", cfg]);
    assert!(!out.contains("plants in days"), "{out}");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (1000, 600));
    let days_png = d.join("F-1-days.png");
    ok(&["timeline", "-c", cfg, "F-1", "--plot", days_png.to_str().unwrap()]);
    // Same data, another axis: the drawings differ.
    assert_ne!(std::fs::read(&png).unwrap(), std::fs::read(&days_png).unwrap());
    let plots = d.join("plots");
    ok(&[
        "timeline",
        "-c",
        cfg,
        "--plots",
        plots.to_str().unwrap(),
        "--degree-days",
    ]);
    assert_eq!(std::fs::read_dir(&plots).unwrap().count(), 6);
}
