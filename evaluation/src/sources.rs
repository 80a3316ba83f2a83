//! Where evaluation data comes from: phyllo-gen dataset manifests and CSV
//! files of human counts.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

/// One image of a phyllo-gen dataset.
#[derive(Debug, Clone)]
pub struct DatasetItem {
    /// The image's path as the manifest gives it, relative to the data set.
    pub name: String,
    /// RGB image.
    pub image: PathBuf,
    /// Panoptic label (16-bit PNG, contract encoding).
    pub label: PathBuf,
    /// View name from the manifest (`0`, `108`, `top`, ...).
    pub view: String,
}

/// Whether the data set in `dir` holds whole camera frames (`phyllo-gen
/// dataset --full-frame`: the first row's `crop` is `[0, 0]`) rather than
/// square crops. Unreadable or older manifests count as crops.
pub fn holds_whole_frames(dir: &Path) -> bool {
    let Ok(text) = std::fs::read_to_string(dir.join("manifest.jsonl")) else {
        return false;
    };
    text.lines()
        .find(|l| !l.trim().is_empty())
        .and_then(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .is_some_and(|row| row["crop"] == serde_json::json!([0, 0]))
}

/// Reads `DIR/manifest.jsonl`, keeping rows of `split` (all rows if `None`).
pub fn read_manifest(dir: &Path, split: Option<&str>) -> anyhow::Result<Vec<DatasetItem>> {
    let path = dir.join("manifest.jsonl");
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut items = Vec::new();
    for (i, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let row: serde_json::Value = serde_json::from_str(line)
            .with_context(|| format!("{} line {}: not JSON", path.display(), i + 1))?;
        let field = |k: &str| -> anyhow::Result<String> {
            Ok(match &row[k] {
                serde_json::Value::String(s) => s.clone(),
                serde_json::Value::Null => bail!("{} line {}: no field {k:?}", path.display(), i + 1),
                v => v.to_string(),
            })
        };
        if split.is_some_and(|s| field("split").ok().as_deref() != Some(s)) {
            continue;
        }
        let name = field("image")?;
        items.push(DatasetItem {
            image: dir.join(&name),
            name,
            label: dir.join(field("label")?),
            view: field("view").unwrap_or_else(|_| "?".into()),
        });
    }
    if items.is_empty() {
        bail!(
            "{} has no rows{}",
            path.display(),
            split.map(|s| format!(" with split {s:?}")).unwrap_or_default()
        );
    }
    Ok(items)
}

/// One real image with a human count.
#[derive(Debug, Clone)]
pub struct HumanCount {
    /// The image.
    pub image: PathBuf,
    /// The human's leaf count.
    pub count: u32,
    /// View parsed from the LemnaTec file name (`SV_108`, `TV_90`, or `?`).
    pub view: String,
    /// Leaf tips the person marked, `[x, y]` in image pixels, when the CSV
    /// has a `tips_xy` column (`leaf_tips.csv`) and the row fills it.
    pub tips: Option<Vec<[f32; 2]>>,
}

/// Reads a CSV with a header holding `file` and `leaf_count` columns, and
/// the tips of an optional `tips_xy` column (a JSON list of `[x, y]`, as in
/// `leaf_tips.csv`); other columns are ignored. Files are looked up in
/// `images`.
pub fn read_counts(csv_path: &Path, images: &Path) -> anyhow::Result<Vec<HumanCount>> {
    let mut rdr =
        csv::Reader::from_path(csv_path).with_context(|| format!("cannot read {}", csv_path.display()))?;
    let headers = rdr
        .headers()
        .with_context(|| format!("{}: no header row", csv_path.display()))?
        .clone();
    let col = |name: &str| {
        headers
            .iter()
            .position(|h| h.trim() == name)
            .with_context(|| format!("{}: no {name:?} column (have {:?})", csv_path.display(), headers))
    };
    let (fc, cc) = (col("file")?, col("leaf_count")?);
    let tc = col("tips_xy").ok();
    let mut out = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let rec = rec.with_context(|| format!("{} row {}", csv_path.display(), i + 2))?;
        let file = rec.get(fc).unwrap_or_default().trim().to_string();
        let count: u32 = rec.get(cc).unwrap_or_default().trim().parse().with_context(|| {
            format!(
                "{} row {}: leaf_count is not a whole number",
                csv_path.display(),
                i + 2
            )
        })?;
        let tips = match tc.and_then(|tc| rec.get(tc)).map(str::trim) {
            None | Some("") => None,
            Some(text) => Some(serde_json::from_str::<Vec<[f32; 2]>>(text).with_context(|| {
                format!(
                    "{} row {}: tips_xy is not a list of [x, y] pairs",
                    csv_path.display(),
                    i + 2
                )
            })?),
        };
        out.push(HumanCount {
            image: images.join(&file),
            count,
            view: view_from_name(&file),
            tips,
        });
    }
    Ok(out)
}

/// The view of a LemnaTec file name: `..._Vis_SV_108.jpg` → `SV_108`.
pub fn view_from_name(name: &str) -> String {
    let Some(at) = name.find("_Vis_") else {
        return "?".into();
    };
    let rest = &name[at + 5..];
    let mut parts = rest.split(['_', '.']);
    match (parts.next(), parts.next()) {
        (Some(kind), Some(angle)) if !angle.is_empty() => format!("{kind}_{angle}"),
        _ => "?".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_from_lemnatec_names() {
        assert_eq!(
            view_from_name("402-127-N55-WW-1_2019-05-10_09-18-07.937_Vis_SV_108.jpg"),
            "SV_108"
        );
        assert_eq!(
            view_from_name("81-133-Tzi25_2018-08-20_04-44-32_Vis_SV_0.Crp.jpg"),
            "SV_0"
        );
        assert_eq!(view_from_name("p_2018-01-01_00-00-00_Vis_TV_90.png"), "TV_90");
        assert_eq!(view_from_name("plain.png"), "?");
    }

    #[test]
    fn counts_csv_by_header_names_with_extra_columns() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("tips.csv");
        std::fs::write(&p, "file,leaf_count,tips_xy\na_Vis_SV_108.jpg,5,\"[[1, 2]]\"\n").unwrap();
        let v = read_counts(&p, Path::new("/imgs")).unwrap();
        assert_eq!(v[0].count, 5);
        assert_eq!(v[0].image, Path::new("/imgs/a_Vis_SV_108.jpg"));
        assert_eq!(v[0].tips, Some(vec![[1.0, 2.0]]));
        std::fs::write(&p, "file,leaf_count,tips_xy\na.jpg,5,\"[[1, 2], [3]]\"\n").unwrap();
        let e = format!("{:#}", read_counts(&p, Path::new("/")).unwrap_err());
        assert!(e.contains("row 2: tips_xy is not a list"), "{e}");
        std::fs::write(&p, "name,count\nx,1\n").unwrap();
        let e = read_counts(&p, Path::new("/")).unwrap_err().to_string();
        assert!(e.contains("no \"file\" column"), "{e}");
    }
}
