//! `[watch] skip_top_views`: the running service counts the side views and
//! never reads the top views, through the start-up scan, live events and
//! later rescans alike; real images, the real model, a real SQLite file.

mod common;

use std::time::Duration;

use common::{small_png, Site};

#[test]
fn top_views_are_never_read_when_skipped() {
    let site = Site::new("workers = 1\n", "skip_top_views = true\n");
    // One day before the service starts (the start-up scan), one after (live events).
    let drop_day = |day: u32| {
        for v in 0..5u32 {
            let name = format!("P1_2018-04-{day:02}_10-00-{:02}_Vis_SV_{}.png", v * 7, v * 36);
            std::fs::write(site.drop.join(name), small_png(10 * day as u64 + v as u64, 96)).unwrap();
        }
        let top = format!("P1_2018-04-{day:02}_10-02-00_Vis_TV_90.png");
        std::fs::write(site.drop.join(top), small_png(1000 + day as u64, 96)).unwrap();
    };
    drop_day(1);
    let mut daemon = site.serve();
    site.wait_running(&mut daemon);
    drop_day(2);
    site.wait_for("ten side views counted", Duration::from_secs(120), || {
        site.q("SELECT COUNT(*) FROM images WHERE state = 'counted'") == 10
    });
    // Past a rescan (every 2 s here): still nothing of the top views.
    std::thread::sleep(Duration::from_secs(5));
    assert_eq!(site.q("SELECT COUNT(*) FROM images"), 10);
    assert_eq!(site.q("SELECT COUNT(*) FROM images WHERE view LIKE 'TV%'"), 0);
    assert_eq!(site.q("SELECT COUNT(*) FROM sessions"), 2);
    daemon.term();
}
