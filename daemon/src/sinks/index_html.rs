//! `index.html` beside the nightly export: one page a breeder opens in a
//! browser, with every plant's summary linked to its timeline plot, the group
//! summaries and their curves, and the CSV tables. Static HTML, no script, so
//! it opens from a file share as well as from a web server.

use std::collections::BTreeMap;
use std::path::Path;

use html_escape::{encode_double_quoted_attribute as attr, encode_text as text};

/// What the page shows.
#[derive(Debug, Default)]
pub struct Index {
    /// When the export ran (shown at the top).
    pub generated_at: String,
    /// The service's health line at that moment (`phyllo status --check`).
    pub health: String,
    /// The CSV files written, with their row counts.
    pub tables: Vec<(String, usize)>,
    /// The `plants` export: header and rows (the first column is the plant id).
    pub plants: (Vec<String>, Vec<Vec<String>>),
    /// Plant id → its plot's file name under `plots/`.
    pub plots: BTreeMap<String, String>,
    /// Plant id → (its newest placed leaf, that leaf's picture under `sites/`).
    pub sites: BTreeMap<String, (u32, String)>,
    /// The `groups.csv` table, when groups are configured.
    pub groups: Option<(Vec<String>, Vec<Vec<String>>)>,
    /// The groups' plot file name, when drawn.
    pub groups_plot: Option<String>,
    /// Plants whose id matches no group pattern.
    pub unmatched: usize,
    /// Images that failed in all, and the newest failures (path, error).
    pub failed: (i64, Vec<(String, String)>),
    /// Sessions in doubt in all, and the review sheet's rows
    /// ([`super::review_sheet::COLUMNS`]) of the most doubtful.
    pub review: (usize, Vec<Vec<String>>),
}

/// Renders the page.
pub fn render(idx: &Index) -> String {
    let mut h = String::new();
    page_head(&mut h, idx);
    groups_section(&mut h, idx);
    problems_section(&mut h, idx);
    due_section(&mut h, idx);
    review_section(&mut h, idx);
    plants_section(&mut h, idx);
    h.push_str("</body>\n</html>\n");
    h
}

/// The document's head and style, when the export ran, the service's health
/// and the CSV tables, so a reader knows how fresh the page is.
fn page_head(h: &mut String, idx: &Index) {
    h.push_str(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>phyllo: leaf counts</title>\n\
         <style>body{font-family:sans-serif;margin:1em auto;padding:0 1em;max-width:1300px;color:#222}\
         .wide{max-width:100%;overflow-x:auto}table{border-collapse:collapse;font-size:90%}\
         th,td{border:1px solid #ccc;padding:3px 6px;text-align:right;overflow-wrap:anywhere}\
         th{background:#eee;vertical-align:bottom}td:first-child,th:first-child{text-align:left}\
         code{overflow-wrap:anywhere}img{max-width:100%;height:auto}</style>\n</head>\n<body>\n",
    );
    h.push_str("<h1>phyllo: leaf counts and emergence</h1>\n");
    h.push_str(&format!(
        "<p>Exported {}. {} plants; click a plant for its timeline plot.</p>\n",
        text(&idx.generated_at),
        idx.plants.1.len()
    ));
    if !idx.health.is_empty() {
        h.push_str(&format!("<p>Service: <code>{}</code></p>\n", text(&idx.health)));
    }
    h.push_str("<p>Tables: ");
    let links: Vec<String> = idx
        .tables
        .iter()
        .map(|(file, rows)| format!("<a href=\"{}\">{}</a> ({rows} rows)", attr(file), text(file)))
        .collect();
    h.push_str(&links.join(", "));
    h.push_str("</p>\n");
}

/// The group summaries and their curves, when groups are configured.
fn groups_section(h: &mut String, idx: &Index) {
    let Some((head, rows)) = &idx.groups else {
        return;
    };
    h.push_str("<h2>Groups</h2>\n");
    if idx.unmatched > 0 {
        h.push_str(&format!(
            "<p>{} plants match no group pattern and are not grouped.</p>\n",
            idx.unmatched
        ));
    }
    table(h, head, rows, |_, cell| text(cell).into_owned());
    if let Some(png) = &idx.groups_plot {
        h.push_str(&format!(
            "<p><img src=\"{}\" alt=\"leaves emerged per group\" loading=\"lazy\"></p>\n",
            attr(png)
        ));
    }
}

/// The images that could not be counted, newest first, when there are any.
fn problems_section(h: &mut String, idx: &Index) {
    let (failed, newest) = &idx.failed;
    if *failed > 0 {
        h.push_str(&format!(
            "<h2>Problems</h2>\n<p>{failed} images could not be counted (the newest {} below; \
             <code>images.csv</code> has every one with its error).</p>\n",
            newest.len()
        ));
        let rows: Vec<Vec<String>> = newest.iter().map(|(p, e)| vec![p.clone(), e.clone()]).collect();
        table(h, &["image".into(), "error".into()], &rows, |_, cell| {
            text(cell).into_owned()
        });
    }
}

/// A table's first column, the plant, links to its plot.
fn plant_linked(idx: &Index) -> impl Fn(usize, &str) -> String + '_ {
    move |col: usize, cell: &str| match (col, idx.plots.get(cell)) {
        (0, Some(png)) => format!("<a href=\"plots/{}\">{}</a>", attr(png), text(cell)),
        _ => text(cell).into_owned(),
    }
}

/// The plants whose next leaf is due or overdue ([`leaves_due`]), when any is.
fn due_section(h: &mut String, idx: &Index) {
    let due = leaves_due(&idx.plants);
    if !due.rows.is_empty() {
        h.push_str(&format!(
            "<h2>Leaves due</h2>\n<p>Plants whose next leaf is due by {} (three days after the newest \
             session, {}) or overdue, soonest first: one phyllochron after each plant's last leaf. \
             A leaf overdue by days may mean a stressed plant or one past its flag leaf.</p>\n",
            text(&due.until),
            text(&due.today)
        ));
        table(
            h,
            &[
                "plant".into(),
                "next leaf".into(),
                "expected".into(),
                "last session".into(),
                "".into(),
            ],
            &due.rows,
            plant_linked(idx),
        );
    }
}

/// The sessions most in doubt, for a person to count by hand, when any is.
fn review_section(h: &mut String, idx: &Index) {
    let (in_doubt, sheet) = &idx.review;
    if !sheet.is_empty() {
        h.push_str(&format!(
            "<h2>Days to check</h2>\n<p>{in_doubt} plant sessions are in doubt (the day's count \
             departs from the timeline, or most side views disagree with it); the {} most doubtful below. \
             Count them by hand, fill in <code>leaf_count</code> in <a href=\"review.csv\">review.csv</a> \
             and hand it to <code>phyllo import</code>: a person's count overrides the model's.</p>\n",
            sheet.len()
        ));
        // The columns a reader needs; the empty view and leaf_count and the
        // image paths stay in the CSV.
        let shown = [0, 1, 4, 5, 6, 7];
        let head: Vec<String> = shown
            .iter()
            .map(|&i| super::review_sheet::COLUMNS[i].to_string())
            .collect();
        let rows: Vec<Vec<String>> = sheet
            .iter()
            .map(|r| shown.iter().map(|&i| r[i].clone()).collect())
            .collect();
        table(h, &head, &rows, plant_linked(idx));
    }
}

/// Every plant's summary, with a thumbnail of its plot after its id when
/// plots were drawn, and where its newest leaf emerged when drawn.
fn plants_section(h: &mut String, idx: &Index) {
    h.push_str("<h2>Plants</h2>\n");
    let (head, rows) = &idx.plants;
    let linked = plant_linked(idx);
    let (thumbs, sites) = (!idx.plots.is_empty(), !idx.sites.is_empty());
    // The added columns carry the plant id; `table` draws them from it.
    let mut head = head.clone();
    if thumbs {
        head.insert(1.min(head.len()), "plot".into());
    }
    if sites {
        head.push("newest leaf seen".into());
    }
    let n = head.len() - 1;
    let rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let mut r = r.clone();
            let id = r.first().cloned().unwrap_or_default();
            if thumbs {
                r.insert(1.min(r.len()), id.clone());
            }
            if sites {
                r.push(id);
            }
            r
        })
        .collect();
    table(h, &head, &rows, |col, cell| match col {
        1 if thumbs => idx.plots.get(cell).map_or(String::new(), |png| {
            format!(
                "<a href=\"plots/{0}\"><img src=\"plots/{0}\" alt=\"{1}: timeline plot\" width=\"160\" \
                 loading=\"lazy\"></a>",
                attr(png),
                attr(cell)
            )
        }),
        _ if sites && col == n => idx.sites.get(cell).map_or(String::new(), |(leaf, png)| {
            format!("<a href=\"sites/{}\">leaf {leaf}</a>", attr(png))
        }),
        _ => linked(col, cell),
    });
}

/// Column names of the tables (as in the CSVs) in words for the page.
const HEADINGS: [(&str, &str); 19] = [
    ("first_session", "first session"),
    ("last_session", "last session"),
    ("leaves_emerged", "leaves emerged"),
    ("living", "living leaves"),
    ("leaves_lost", "leaves lost"),
    ("phyllochron_days", "days per leaf"),
    ("phyllochron_cd", "degree-days per leaf"),
    ("phyllochron_plants", "plants with days per leaf"),
    ("phyllochron_cd_plants", "plants with degree-days per leaf"),
    ("events", "leaves dated"),
    ("last_emergence", "last leaf emerged"),
    ("climate_zone", "climate zone"),
    ("next_leaf", "next leaf"),
    ("next_leaf_expected", "next leaf expected"),
    ("timestamp", "session"),
    ("phyllo_count", "phyllo's count"),
    ("timeline", "timeline says"),
    ("views", "count per view"),
    ("why", "why in doubt"),
];

/// A column name in words: `phyllochron_days` → "days per leaf",
/// `leaves_emerged_sd` → "leaves emerged (SD)"; a name not known has its
/// underscores read as spaces.
fn heading(name: &str) -> String {
    let known = |n: &str| {
        HEADINGS
            .iter()
            .find(|(raw, _)| *raw == n)
            .map(|(_, w)| w.to_string())
    };
    let spread = [("_mean", "mean"), ("_sd", "SD")]
        .iter()
        .find_map(|(suffix, what)| Some((name.strip_suffix(suffix)?, what)));
    known(name)
        .or_else(|| {
            spread.map(|(base, what)| format!("{} ({what})", known(base).unwrap_or(base.replace('_', " "))))
        })
        .unwrap_or_else(|| name.replace('_', " "))
}

/// A table of `rows` under `head` (column names, shown in words with the
/// name itself as the tooltip), in a wrapper that scrolls rather than widen
/// the page; `cell` draws each cell from its column and text.
fn table(h: &mut String, head: &[String], rows: &[Vec<String>], cell: impl Fn(usize, &str) -> String) {
    h.push_str("<div class=\"wide\"><table>\n<tr>");
    for c in head {
        let words = heading(c);
        if words == *c {
            h.push_str(&format!("<th>{}</th>", text(c)));
        } else {
            h.push_str(&format!("<th title=\"{}\">{}</th>", attr(c), text(&words)));
        }
    }
    h.push_str("</tr>\n");
    for r in rows {
        h.push_str("<tr>");
        for (i, c) in r.iter().enumerate() {
            h.push_str(&format!("<td>{}</td>", cell(i, c)));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table></div>\n");
}

/// The "Leaves due" section's rows and the days it spans.
struct Due {
    /// The newest session of any plant (date), standing for today.
    today: String,
    /// Three days after it.
    until: String,
    /// plant, next leaf, expected, last session, how late.
    rows: Vec<Vec<String>>,
}

/// From the `plants` table: plants whose next leaf is expected within three
/// days of the newest session, or before their own last session (overdue).
fn leaves_due((head, rows): &(Vec<String>, Vec<Vec<String>>)) -> Due {
    let col = |name: &str| head.iter().position(|h| h == name);
    let none = Due {
        today: String::new(),
        until: String::new(),
        rows: Vec::new(),
    };
    let (Some(leaf), Some(expected), Some(last)) =
        (col("next_leaf"), col("next_leaf_expected"), col("last_session"))
    else {
        return none;
    };
    let parse = |s: &str| crate::store::parse_iso(s).ok();
    let Some(today) = rows.iter().filter_map(|r| parse(&r[last])).max() else {
        return none;
    };
    let until = today + chrono::Duration::days(3);
    let mut due: Vec<(chrono::NaiveDateTime, Vec<String>)> = rows
        .iter()
        .filter_map(|r| {
            let at = parse(&r[expected])?;
            let seen = parse(&r[last])?;
            if at > until {
                return None;
            }
            let note = crate::domain::forecast::days_overdue(at, seen).map_or(String::new(), |late| {
                format!("overdue by {late:.1} days at its last session")
            });
            Some((
                at,
                vec![
                    r[0].clone(),
                    r[leaf].clone(),
                    r[expected].get(..16).unwrap_or(&r[expected]).to_string(),
                    r[last].get(..16).unwrap_or(&r[last]).to_string(),
                    note,
                ],
            ))
        })
        .collect();
    due.sort_by_key(|d| d.0);
    Due {
        today: today.format("%Y-%m-%d").to_string(),
        until: until.format("%Y-%m-%d").to_string(),
        rows: due.into_iter().map(|d| d.1).collect(),
    }
}

/// Writes the page to `out`, renamed into place whole.
pub fn write(out: &Path, idx: &Index) -> anyhow::Result<()> {
    crate::files::atomic::replace(out, ".html", |tmp| Ok(std::fs::write(tmp, render(idx))?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plants_link_to_their_plots_and_every_text_is_escaped() {
        let evil = "x'\"><script>alert(1)</script>";
        let idx = Index {
            generated_at: "2026-12-05 02:30".into(),
            health: "phyllo WARNING: 3 images failed in the last 24 h".into(),
            tables: vec![("plants.csv".into(), 2)],
            plants: (
                vec!["plant".into(), "leaves_emerged".into()],
                vec![vec!["A-1".into(), "7".into()], vec![evil.into(), "3".into()]],
            ),
            plots: BTreeMap::from([("A-1".to_string(), "A-1.png".to_string())]),
            sites: BTreeMap::from([("A-1".to_string(), (7, "A-1-leaf-07-0a1b2c3d.png".to_string()))]),
            groups: Some((vec!["genotype".into()], vec![vec!["<b>".into()]])),
            groups_plot: Some("groups.png".into()),
            unmatched: 1,
            failed: (3, vec![("drop/bad<1>.png".into(), "truncated PNG".into())]),
            review: (
                7,
                vec![[
                    "A-1",
                    "2026-11-02T08:00:00.000",
                    "human",
                    "",
                    "8",
                    "7",
                    "SV_0 8 SV_36 7",
                    "count 8 where the timeline has 7",
                    "a<1>.png",
                ]
                .map(String::from)
                .to_vec()],
            ),
        };
        let page = render(&idx);
        assert!(page.contains("<a href=\"plots/A-1.png\">A-1</a>"), "{page}");
        // The newest leaf links to where it emerged; a plant with none gets an empty cell.
        assert!(
            page.contains("<th>newest leaf seen</th>")
                && page.contains("<td><a href=\"sites/A-1-leaf-07-0a1b2c3d.png\">leaf 7</a></td>")
                && page.contains("<td>3</td><td></td></tr>"),
            "{page}"
        );
        assert!(
            !page.contains("<script>") && page.contains("&lt;script&gt;"),
            "{page}"
        );
        assert!(page.contains("<td>&lt;b&gt;</td>"));
        assert!(page.contains("<img src=\"groups.png\""));
        assert!(page.contains("1 plants match no group pattern"));
        assert!(page.contains("3 images could not be counted"));
        assert!(page.contains("7 plant sessions are in doubt"), "{page}");
        assert!(
            page.contains(
                "<tr><td><a href=\"plots/A-1.png\">A-1</a></td><td>2026-11-02T08:00:00.000</td>\
                 <td>8</td><td>7</td><td>SV_0 8 SV_36 7</td><td>count 8 where the timeline has 7</td></tr>"
            ),
            "{page}"
        );
        assert!(!page.contains("a<1>.png"), "image paths stay in the sheet");
        assert!(page.contains("<code>phyllo WARNING: 3 images failed in the last 24 h</code>"));
        assert!(
            page.contains("<td>drop/bad&lt;1&gt;.png</td><td>truncated PNG</td>"),
            "{page}"
        );
        assert!(!page.contains("Leaves due"), "no forecasts, no section");
        let dir = tempfile::tempdir().unwrap();
        write(&dir.path().join("index.html"), &idx).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.path().join("index.html")).unwrap(),
            page
        );
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temporary file left"
        );
    }

    #[test]
    fn columns_read_in_words_and_plants_show_their_plot_small() {
        let idx = Index {
            plants: (
                ["plant", "phyllochron_days", "phyllochron_cd", "leaves_emerged"]
                    .map(String::from)
                    .to_vec(),
                vec![
                    ["A-1", "2.1", "40", "7"].map(String::from).to_vec(),
                    ["B-2", "", "", "1"].map(String::from).to_vec(),
                ],
            ),
            plots: BTreeMap::from([("A-1".to_string(), "A-1.png".to_string())]),
            groups: Some((
                ["genotype", "leaves_emerged_sd", "phyllochron_days_mean"]
                    .map(String::from)
                    .to_vec(),
                vec![],
            )),
            ..Index::default()
        };
        let page = render(&idx);
        for th in [
            "<th title=\"phyllochron_days\">days per leaf</th>",
            "<th title=\"phyllochron_cd\">degree-days per leaf</th>",
            "<th title=\"leaves_emerged\">leaves emerged</th>",
            "<th title=\"leaves_emerged_sd\">leaves emerged (SD)</th>",
            "<th title=\"phyllochron_days_mean\">days per leaf (mean)</th>",
            "<th>plant</th><th>plot</th>",
            "<th>genotype</th>",
        ] {
            assert!(page.contains(th), "{th} in {page}");
        }
        assert!(!page.contains(">phyllochron_days<"), "{page}");
        // A plot's thumbnail, small and loaded when scrolled to; none without a plot.
        assert!(
            page.contains(
                "<tr><td><a href=\"plots/A-1.png\">A-1</a></td><td><a href=\"plots/A-1.png\">\
                 <img src=\"plots/A-1.png\" alt=\"A-1: timeline plot\" width=\"160\" loading=\"lazy\"></a></td>\
                 <td>2.1</td>"
            ),
            "{page}"
        );
        assert!(page.contains("<tr><td>B-2</td><td></td><td></td>"), "{page}");
        // Fits a laptop screen: the page is bounded and wide tables scroll in their box.
        assert!(page.contains("max-width:1300px") && page.contains(".wide{max-width:100%;overflow-x:auto}"));
        assert_eq!(
            page.matches("<div class=\"wide\"><table>").count(),
            page.matches("<table>").count()
        );
        assert!(!page.contains("nowrap"));
        assert_eq!(heading("some_new_column"), "some new column");
    }

    #[test]
    fn leaves_due_soonest_first_with_the_overdue() {
        let head: Vec<String> = ["plant", "last_session", "next_leaf", "next_leaf_expected"]
            .map(String::from)
            .to_vec();
        let row = |p: &str, last: &str, leaf: &str, at: &str| [p, last, leaf, at].map(String::from).to_vec();
        let rows = vec![
            row("late", "2026-11-10T08:00:00.000", "9", "2026-11-08T08:00:00.000"),
            row("soon", "2026-11-10T08:00:00.000", "7", "2026-11-12T20:00:00.000"),
            row("later", "2026-11-10T08:00:00.000", "5", "2026-11-20T08:00:00.000"),
            row("none", "2026-11-10T08:00:00.000", "", ""),
        ];
        let due = leaves_due(&(head, rows));
        assert_eq!(
            (due.today.as_str(), due.until.as_str()),
            ("2026-11-10", "2026-11-13")
        );
        let plants: Vec<&str> = due.rows.iter().map(|r| r[0].as_str()).collect();
        assert_eq!(plants, ["late", "soon"]);
        assert_eq!(due.rows[0][4], "overdue by 2.0 days at its last session");
        assert_eq!(due.rows[1][2], "2026-11-12T20:00");
    }
}
