//! `phyllo groups`: summaries by genotype and treatment, comparisons
//! between groups (within blocks too), and the export's group files.

use std::path::Path;

use crate::common::{ok, phyllo};
use crate::{site_config, steady_counts, two_genotypes, two_genotypes_with};

/// `phyllo groups` and the nightly export's group files, on plants of two
/// genotypes under two treatments whose leaf numbers are known: genotype A
/// gains a leaf every 2 days, B every 4, both from 4 leaves; one plant id
/// outside the pattern is listed, not grouped.
#[test]
fn groups_summarise_genotypes_and_treatments() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (cfg_s, base) = site_config(d, &format!("[export]\ndir = {:?}\n", d.join("exports")));
    let cfg_s = cfg_s.as_str();
    let cfg = Path::new(cfg_s);
    let plants = [
        "1-A-WW-1", "2-A-WW-2", "3-A-WL-1", "4-B-WW-1", "5-B-WW-2", "6-B-WL-1", "stray",
    ];
    let every = plants.map(|p| (p, if p.contains("-B-") { 4 } else { 2 }));
    let obs = steady_counts(&every, 13, &[0, 36, 72, 108, 144]);
    std::fs::write(d.join("obs.csv"), obs).unwrap();
    ok(&["import", "-c", cfg_s, d.join("obs.csv").to_str().unwrap()]);

    // A monitor asking before the service ever ran, and about a missing database.
    let check = phyllo(&["status", "-c", cfg_s, "--check"]);
    assert_eq!(check.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&check.stdout).starts_with("phyllo CRITICAL: service never started"));
    let other = d.join("other.toml");
    std::fs::write(
        &other,
        format!(
            "drop_dir = {:?}\ndatabase = {:?}\n",
            d.join("drop"),
            d.join("none.sqlite")
        ),
    )
    .unwrap();
    let check = phyllo(&["status", "-c", other.to_str().unwrap(), "--check"]);
    assert_eq!(check.status.code(), Some(3));
    assert!(String::from_utf8_lossy(&check.stdout).starts_with("phyllo UNKNOWN: database"));

    // Without a pattern the command says what to set.
    let out = phyllo(&["groups", "-c", cfg_s]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("[groups] pattern"));

    std::fs::write(
        cfg,
        format!(
            "{base}[groups]\npattern = '^(?P<pot>\\d+)-(?P<genotype>[A-Z]+)-(?P<treatment>WW|WL)-(?P<rep>\\d+)$'\nby = [\"genotype\", \"treatment\"]\n"
        ),
    )
    .unwrap();
    let out = phyllo(&["groups", "-c", cfg_s, "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("plants matching no [groups] pattern (1): stray"));
    let rep: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let groups: Vec<String> = rep["summaries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| {
            g["group"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_str().unwrap())
                .collect::<Vec<_>>()
                .join("/")
        })
        .collect();
    assert_eq!(groups, ["A/WL", "A/WW", "B/WL", "B/WW"]);
    let ww = |i: usize, k: &str| rep["summaries"][i][k]["mean"].as_f64().unwrap();
    // Day 12: A has 4 + 12/2 = 10 leaves, B 4 + 12/4 = 7; A's phyllochron 2 days, B's 4.
    assert_eq!(rep["summaries"][1]["plants"], 2);
    assert!(
        (ww(1, "leaves_emerged") - 10.0).abs() < 1e-9,
        "{}",
        rep["summaries"][1]
    );
    assert!(
        (ww(3, "leaves_emerged") - 7.0).abs() < 1e-9,
        "{}",
        rep["summaries"][3]
    );
    assert!(
        (ww(1, "phyllochron_days") - 2.0).abs() < 0.2,
        "{}",
        rep["summaries"][1]
    );
    assert!(
        (ww(3, "phyllochron_days") - 4.0).abs() < 0.4,
        "{}",
        rep["summaries"][3]
    );
    assert_eq!(rep["unmatched"], serde_json::json!(["stray"]));

    // The nightly export writes both tables and the plot beside the others.
    ok(&["export", "-c", cfg_s]);
    let exports = d.join("exports");
    let groups_csv = std::fs::read_to_string(exports.join("groups.csv")).unwrap();
    let mut lines = groups_csv.lines();
    assert!(lines
        .next()
        .unwrap()
        .starts_with("genotype,treatment,plants,leaves_emerged_mean,leaves_emerged_sd"));
    assert!(lines.nth(1).unwrap().starts_with("A,WW,2,10,0,"), "{groups_csv}");
    let days = std::fs::read_to_string(exports.join("group_days.csv")).unwrap();
    assert_eq!(days.lines().count(), 1 + 4 * 13);
    assert!(days.contains("B,WW,2026-11-13,2,7,0,7,0"), "{days}");
    let png = image::open(exports.join("groups.png")).unwrap();
    assert_eq!((png.width(), png.height()), (1000, 600));
    // One page links it all: each plant to its plot, the groups, the tables.
    let page = std::fs::read_to_string(exports.join("index.html")).unwrap();
    for p in plants {
        assert!(
            page.contains(&format!("<a href=\"plots/{p}.png\">{p}</a>")),
            "{p} in {page}"
        );
        assert!(exports.join("plots").join(format!("{p}.png")).exists());
    }
    for f in [
        "groups.png",
        "groups.csv",
        "group_days.csv",
        "plants.csv",
        "events.csv",
    ] {
        assert!(page.contains(&format!("\"{f}\"")), "{f} in {page}");
    }
    assert!(
        page.contains("<td>B</td><td>WL</td><td>1</td><td>7</td>"),
        "{page}"
    );
    // The page says how the service stood when it was written (here: it never ran).
    assert!(
        page.contains("Service: <code>phyllo CRITICAL: service never started"),
        "{page}"
    );
}

/// `phyllo groups --compare`: every two groups tested against each other
/// (Welch), on the terminal, in JSON and as `group_pairs.csv`.
#[test]
fn groups_compare_tests_every_two_groups() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cfg = two_genotypes(d);
    let cfg = cfg.as_str();
    let rep: serde_json::Value =
        serde_json::from_str(&ok(&["groups", "-c", cfg, "--compare", "--json"])).unwrap();
    let pairs = rep["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 2, "{pairs:?}");
    let ph = &pairs[0];
    assert_eq!(
        (ph["measure"].as_str(), ph["a"][0].as_str(), ph["b"][0].as_str()),
        (Some("phyllochron_days"), Some("F"), Some("S"))
    );
    // F averages 2.33 days per leaf, S 4.33: two days apart, well outside chance.
    let diff = ph["difference"].as_f64().unwrap();
    assert!((diff + 2.0).abs() < 0.3, "{ph}");
    let (lo, hi) = (ph["ci95"][0].as_f64().unwrap(), ph["ci95"][1].as_f64().unwrap());
    assert!(lo < diff && diff < hi && hi < 0.0, "{ph}");
    assert!(ph["p"].as_f64().unwrap() < 0.05, "{ph}");
    assert_eq!(pairs[1]["measure"], "leaves_emerged");
    let table = ok(&["groups", "-c", cfg, "--compare"]);
    assert!(table.contains("phyllochron_days\tF − S\t3 / 3\t-2."), "{table}");
    let csv_dir = d.join("csv");
    ok(&["groups", "-c", cfg, "--csv", csv_dir.to_str().unwrap()]);
    let written = std::fs::read_to_string(csv_dir.join("group_pairs.csv")).unwrap();
    assert!(written.starts_with("measure,genotype_a,genotype_b,plants_a,plants_b,mean_a,mean_b,difference,ci95_low,ci95_high,t,df,p,p_holm,blocks\r\n"), "{written}");
    assert_eq!(written.lines().count(), 3, "{written}");
}

/// `[groups] block`: the same plants compared within replicate blocks (the
/// number in each id), in the table, the JSON and `group_pairs.csv`.
#[test]
fn groups_compare_within_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // two_genotypes' ids are genotype-replicate: F-1 and S-1 stand in block 1.
    let cfg = two_genotypes_with(d, "");
    std::fs::write(
        &cfg,
        std::fs::read_to_string(&cfg).unwrap().replace(
            "pattern = '^(?P<genotype>[A-Z]+)-\\d+$'",
            "pattern = '^(?P<genotype>[A-Z]+)-(?P<rep>\\d+)$'\nby = ['genotype']\nblock = 'rep'",
        ),
    )
    .unwrap();
    let cfg = cfg.as_str();
    let rep: serde_json::Value =
        serde_json::from_str(&ok(&["groups", "-c", cfg, "--compare", "--json"])).unwrap();
    let emerged = rep["pairs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["measure"] == "leaves_emerged")
        .unwrap_or_else(|| panic!("{rep}"));
    assert_eq!(emerged["blocks"], 3, "{emerged}");
    assert_eq!(emerged["df"], 2.0, "{emerged}");
    let table = ok(&["groups", "-c", cfg, "--compare"]);
    assert!(
        table.contains("compared within blocks of rep")
            && table.contains("leaves_emerged\tF − S\t3 / 3 in 3 blocks\t+"),
        "{table}"
    );
    let csv_dir = d.join("csv");
    ok(&["groups", "-c", cfg, "--csv", csv_dir.to_str().unwrap()]);
    let written = std::fs::read_to_string(csv_dir.join("group_pairs.csv")).unwrap();
    assert!(
        written
            .lines()
            .any(|l| l.starts_with("leaves_emerged,F,S,3,3,") && l.ends_with(",3")),
        "{written}"
    );
}
