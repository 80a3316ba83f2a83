//! Images filed under the wrong plant (a misread barcode), moved to the
//! right one with an `image,plant` sheet beside the running service, and
//! moved back with `phyllo import --undo`; real images counted by the real
//! model, a real SQLite file. Then days without a new image, which
//! `phyllo status --check` reports.

mod common;

use std::time::Duration;

use common::{flat_name, small_png, Site};

#[test]
fn a_sheet_moves_misfiled_images_to_their_plant_and_undo_moves_them_back() {
    let site = Site::new("workers = 1\n", "");
    let mut daemon = site.serve();
    site.wait_running(&mut daemon);
    // P01 on days 1 and 2; day 3's five views were read as P9X.
    let mut misfiled = Vec::new();
    for (day, plant) in [(1, "P01"), (2, "P01"), (3, "P9X")] {
        for v in 0..5u32 {
            let name = flat_name(plant, day, v * 7, v * 36);
            std::fs::write(site.drop.join(&name), small_png(100 * day as u64 + v as u64, 96)).unwrap();
            if plant == "P9X" {
                misfiled.push(name);
            }
        }
    }
    site.wait_for("15 images counted", Duration::from_secs(120), || {
        site.q("SELECT COUNT(*) FROM images WHERE state = 'counted'") == 15
    });
    let sessions = |plant: &str| {
        site.q(&format!(
            "SELECT COUNT(*) FROM sessions s JOIN plants p ON p.id = s.plant_id WHERE p.name = '{plant}'"
        ))
    };
    assert_eq!((sessions("P01"), sessions("P9X")), (2, 1));

    // A sheet naming an image the database does not hold moves nothing.
    let bad = site.tmp.path().join("bad-fix.csv");
    std::fs::write(
        &bad,
        format!("image,plant\n{},P01\nnot-there.png,P01\n", misfiled[0]),
    )
    .unwrap();
    let out = site.phyllo(&["import", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad-fix.csv: line 3: no image \"not-there.png\""),
        "{err}"
    );
    assert_eq!(sessions("P9X"), 1, "nothing moved");

    let fix = site.tmp.path().join("fix.csv");
    let mut sheet = String::from("image,plant\n");
    for name in &misfiled {
        sheet += &format!("{name},P01\n");
    }
    std::fs::write(&fix, sheet).unwrap();
    let out = site.phyllo(&["import", fix.to_str().unwrap()]);
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        printed.contains("imported 5 image moves (2 plants refitted)"),
        "{printed}"
    );
    assert_eq!((sessions("P01"), sessions("P9X")), (3, 0));
    assert_eq!(
        site.q("SELECT COUNT(*) FROM observations o JOIN plants p ON p.id = o.plant_id WHERE p.name = 'P01'"),
        15
    );
    assert_eq!(
        site.q("SELECT COUNT(*) FROM images i JOIN plants p ON p.id = i.plant_id WHERE p.name = 'P01'"),
        15
    );
    assert_eq!(site.q("SELECT COUNT(*) FROM feed WHERE kind = 'reassign'"), 1);
    // The service goes on counting beside it: a new image of P01 lands on the moved plant.
    std::fs::write(site.drop.join(flat_name("P01", 4, 0, 0)), small_png(999, 96)).unwrap();
    site.wait_for("the day-4 image counted", Duration::from_secs(60), || {
        sessions("P01") == 4
    });

    let out = site.phyllo(&["import", "--undo", "fix.csv"]);
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && printed.contains("moved 5 images back to the plants they came from"),
        "{printed}"
    );
    assert_eq!((sessions("P01"), sessions("P9X")), (3, 1));
    assert_eq!(site.q("SELECT COUNT(*) FROM reassignments"), 0);
    daemon.term();

    // Three days later with no new image, a monitor hears of it.
    rusqlite::Connection::open(&site.db)
        .unwrap()
        .execute(
            "UPDATE images SET first_seen = strftime('%Y-%m-%dT%H:%M:%fZ', 'now', '-3 days')",
            [],
        )
        .unwrap();
    let check = site.phyllo(&["status", "--check"]);
    let line = String::from_utf8_lossy(&check.stdout);
    assert!(line.contains("no new image for 72 h"), "{line}");
}
