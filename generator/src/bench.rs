//! `phyllo-gen bench`: rays per second and image + label pairs per second at
//! the default training quality, PNG encoding included.

use crate::dataset::plan_plant;
use crate::plant::{preset::Preset, Plant};
use crate::render::{self, Quality, Scene, Stage, View};
use crate::{png_io, rng, sampling};
use std::time::Instant;

/// Renders `pairs` dataset pairs (cycling the six views over a few plants)
/// and prints throughput.
pub fn run(pairs: u32, size: u32, quality: Quality, seed: u64) -> anyhow::Result<()> {
    let presets = Preset::builtins()?
        .into_iter()
        .filter(|p| p.weight > 0.0)
        .collect::<Vec<_>>();
    let views = ["0", "36", "72", "108", "144", "top"].map(|v| View::parse(v).expect("valid view"));
    let frame_height = phyllo_contract::Contract::embedded().input.frame_height;
    let start = Instant::now();
    let mut rays = 0u64;
    let mut tris = 0usize;
    let mut build_s = 0.0f64;
    let mut done = 0u32;
    let mut plant_index = 0u64;
    while done < pairs {
        let t0 = Instant::now();
        let plan = plan_plant(
            &presets,
            &Default::default(),
            &crate::sampling::ZoomRange::NONE,
            seed,
            plant_index,
        );
        let plant = Plant::build(&plan.traits, plan.age);
        let stage = Stage::new(&plant, &plan.preset.colour, [0.3, 0.3, 0.1], &plan.look);
        build_s += t0.elapsed().as_secs_f64();
        tris += stage.triangles();
        for view in views {
            if done >= pairs {
                break;
            }
            let scene = Scene::new(&stage, &plan.look, view);
            let camera = render::camera_for(view, &plan.look, frame_height);
            let window = sampling::crop_window(&scene, &camera, view, size);
            let out = render::render(
                &scene,
                &camera,
                &plan.look,
                window,
                quality,
                rng::derive(seed, "bench", u64::from(done)),
            )?;
            let (a, b) = rayon::join(|| png_io::rgb_png(&out.rgb), || png_io::label_png(&out.label));
            a?;
            b?;
            rays += out.rays;
            done += 1;
        }
        plant_index += 1;
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "phyllo-gen bench: {done} pairs at {size}x{size}, spp {} depth {}, {} threads",
        quality.spp,
        quality.max_depth,
        rayon::current_num_threads()
    );
    println!(
        "plants built: {plant_index} (avg {} triangles incl. pot), build+BVH {:.3} s total",
        tris / plant_index as usize,
        build_s
    );
    println!(
        "rays: {rays} in {secs:.2} s = {:.2} M rays/s",
        rays as f64 / secs / 1e6
    );
    println!(
        "pairs/s: {:.2} (image + label, PNG encoding included)",
        f64::from(done) / secs
    );
    Ok(())
}
