//! `phyllo count`: count leaves in image files, one result per file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use phyllo_inference::{Counter, ImageFacts, InferenceError};
use serde_json::json;

use super::counter_args::CounterArgs;
// `phyllo review --overlays` draws its pictures the same way.
pub(super) use phyllo_inference::overlay::render_encoded as render_overlay;

/// Arguments of `phyllo count`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model and runtime options.
    #[command(flatten)]
    pub counter: CounterArgs,
    /// One JSON object per input on stdout.
    #[arg(long)]
    pub json: bool,
    /// Write an overlay PNG per image into this directory.
    #[arg(long, value_name = "DIR")]
    pub overlay: Option<PathBuf>,
    /// Image files (PNG, JPEG, TIFF).
    #[arg(required = true, value_name = "IMAGE")]
    pub images: Vec<PathBuf>,
}

/// Counts every image; a failed image is reported and the others still run.
/// Exit status 1 if any image failed.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let counter = Counter::new(args.counter.config()?)?;
    let info = counter.model_info();
    if !info.trained {
        eprintln!(
            "phyllo: warning: model {} is UNTRAINED (phyllo.trained != true): counts are meaningless",
            info.path.display()
        );
    }
    if let Some(dir) = &args.overlay {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create overlay directory {}", dir.display()))?;
    }
    let has_tips = info.has_tips;
    let mut failed = 0usize;
    let mut drawn = 0usize;
    let stdout = std::io::stdout();
    for path in &args.images {
        // Loose files, not the drop directory's: no `[names]` to read them
        // by, so the evaluation's file-name rule says what each image is.
        let facts = phyllo_evaluation::image_names::facts_for(path);
        let outcome = count_one(&counter, path, &facts, args.overlay.as_deref());
        let mut out = stdout.lock();
        match outcome {
            Ok((r, overlay)) => {
                drawn += usize::from(overlay.is_some());
                if args.json {
                    let mut v = serde_json::to_value(&r)?;
                    v["file"] = json!(path);
                    v["model"] = json!(counter.model_id_for(facts.view));
                    if let Some(o) = overlay {
                        v["overlay"] = json!(o);
                    }
                    writeln!(out, "{v}")?;
                } else {
                    // With a tip model, the tips found beside the leaves
                    // counted (by the count rule), so the two can be compared.
                    let tips = if has_tips {
                        format!("\t{} tips", r.tips.len())
                    } else {
                        String::new()
                    };
                    writeln!(
                        out,
                        "{}\t{} leaves{tips}\t({} tiles, {:.0} ms{})",
                        path.display(),
                        r.leaf_count,
                        r.tiles,
                        r.ms.total,
                        zoom_note(r.camera.as_ref())
                    )?;
                }
            }
            Err(e) => {
                failed += 1;
                if args.json {
                    writeln!(out, "{}", json!({"file": path, "error": e.to_string()}))?;
                } else {
                    drop(out);
                    eprintln!("phyllo: {e}");
                }
            }
        }
    }
    if let Some(dir) = &args.overlay {
        // On stderr, so that the counts on stdout stay one line per image.
        eprintln!("overlays: {drawn} drawn into {}", dir.display());
    }
    Ok(if failed > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

fn count_one(
    counter: &Counter,
    path: &Path,
    facts: &ImageFacts,
    overlay_dir: Option<&Path>,
) -> Result<(phyllo_inference::CountResult, Option<std::path::PathBuf>), InferenceError> {
    if path.is_dir() {
        return Err(InferenceError::image(path, "is a directory, not an image file"));
    }
    let bytes = std::fs::read(path).map_err(|e| InferenceError::image(path, format!("cannot read: {e}")))?;
    let analysis = counter.analyse_bytes(path, facts, &bytes)?;
    let Some(dir) = overlay_dir else {
        return Ok((analysis.result, None));
    };
    let drawn = render_overlay(counter, path, &bytes, &analysis)?;
    let out = phyllo_evaluation::image_names::overlay_path(dir, path, "overlay");
    drawn
        .save(&out)
        .map_err(|e| InferenceError::image(&out, format!("cannot write overlay: {e}")))?;
    Ok((analysis.result, Some(out)))
}

/// `, camera zoom 2.0 (back panel)` where the count assumed a zoomed camera,
/// nothing at the contract's zoom.
fn zoom_note(camera: Option<&phyllo_inference::camera_scale::CameraScale>) -> String {
    use phyllo_inference::camera_scale::ScaleSource;
    match camera {
        Some(c) if c.camera_zoom != 1.0 => {
            let how = match c.source {
                ScaleSource::BackPanel => "back panel",
                ScaleSource::Pinned => "pinned",
                ScaleSource::Contract | ScaleSource::Given => "given",
            };
            format!(", camera zoom {:.2} ({how})", c.camera_zoom)
        }
        _ => String::new(),
    }
}
