//! Bad input, one case per kind, against the real `phyllo` binary and the
//! shipped model. Every file lands in one running daemon; each case states
//! what must happen to it:
//!
//! - `Counted`: an unusual but valid image (16-bit, grey, RGBA, CMYK, TIFF,
//!   odd names): the model sees it as RGB8 and it is counted;
//! - `Failed(what)`: recorded in the database as failed, with an error that
//!   names the file and says `what` went wrong;
//! - `Ignored`: not an image file phyllo looks at (wrong extension, hidden,
//!   a directory, a FIFO): never recorded, never opened.
//!
//! Afterwards a good image still gets counted: nothing stops the service.
//! Model and config problems stop `phyllo serve` before it starts (exit 2,
//! a message naming the file and the problem), which is what a systemd
//! service should do with a broken installation.
//!
//! `fixtures/cmyk.jpg` is a 64×64 CMYK JPEG made with Pillow for this test
//! (`Image.fromarray(a, 'CMYK').save('cmyk.jpg')`); the `image` crate cannot
//! write CMYK.

mod common;

use std::path::Path;
use std::time::Duration;

use common::*;
use image::{DynamicImage, ImageBuffer, ImageFormat};

#[derive(Debug, Clone, PartialEq)]
enum Expect {
    Counted,
    Failed(&'static str),
    Ignored,
}
use Expect::*;

/// How a case puts its file into the drop directory.
enum Make {
    Bytes(Vec<u8>),
    Dir,
    Fifo,
    Sparse(u64),
    Link(std::path::PathBuf),
    Unreadable(Vec<u8>),
}

struct Case {
    kind: &'static str,
    /// Relative path in the drop directory.
    rel: String,
    make: Make,
    expect: Expect,
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn chunk(kind: &[u8], data: &[u8]) -> Vec<u8> {
    let mut out = (data.len() as u32).to_be_bytes().to_vec();
    out.extend(kind);
    out.extend(data);
    let mut c = kind.to_vec();
    c.extend(data);
    out.extend(crc32(&c).to_be_bytes());
    out
}

/// A PNG whose header claims `w`×`h` RGB with a tiny (valid-CRC) body: a
/// decompression bomb's header.
fn png_claiming(w: u32, h: u32) -> Vec<u8> {
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(chunk(b"IHDR", &ihdr));
    out.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]));
    out.extend(chunk(b"IEND", &[]));
    out
}

/// A noisy RGB image (compresses badly, so truncation cuts real data).
fn noise(w: u32, h: u32, seed: u64) -> image::RgbImage {
    let mut rng = Rng(seed.wrapping_mul(2).wrapping_add(1));
    ImageBuffer::from_fn(w, h, |_, _| {
        let v = rng.next().to_le_bytes();
        image::Rgb([v[0], v[1], v[2]])
    })
}

fn name(plant: &str, n: u32) -> String {
    flat_name(plant, 1 + n % 28, n % 60, 0)
}

fn cases(site: &Site) -> Vec<Case> {
    let png = |img: DynamicImage| encode(img, ImageFormat::Png);
    let rgb = noise(64, 64, 1);
    let good_png = png(DynamicImage::ImageRgb8(noise(96, 96, 2)));
    let good_jpg = encode(DynamicImage::ImageRgb8(noise(96, 96, 3)), ImageFormat::Jpeg);
    let mut bad_crc = png(DynamicImage::ImageRgb8(noise(48, 48, 4)));
    let mid = bad_crc.len() / 2;
    bad_crc[mid] ^= 0xFF; // inside IDAT: a CRC and zlib error
    let outside = site.tmp.path().join("outside.png");
    std::fs::write(&outside, small_png(77, 64)).unwrap();
    let mut c = Vec::new();
    let mut n = 0;
    let mut add = |kind: &'static str, rel: String, make: Make, expect: Expect| {
        c.push(Case {
            kind,
            rel,
            make,
            expect,
        })
    };
    let mut next = || {
        n += 1;
        n
    };
    add(
        "zero-byte file",
        name("Z", next()),
        Make::Bytes(vec![]),
        Failed("empty (0 bytes)"),
    );
    add(
        "truncated PNG",
        name("TP", next()),
        Make::Bytes(good_png[..good_png.len() * 6 / 10].to_vec()),
        Failed("truncated"),
    );
    add(
        "truncated JPEG",
        name("TJ", next()).replace(".png", ".jpg"),
        Make::Bytes(good_jpg[..good_jpg.len() * 6 / 10].to_vec()),
        Failed("truncated Jpeg"),
    );
    add(
        "PNG with a corrupt IDAT",
        name("CRC", next()),
        Make::Bytes(bad_crc),
        Failed("corrupt"),
    );
    add(
        "garbage with an image extension",
        name("G", next()),
        Make::Bytes((0..5000u32).map(|i| (i * 7919 % 251) as u8).collect()),
        Failed("unrecognised content"),
    );
    add(
        "a text file named .jpg",
        name("T", next()).replace(".png", ".jpg"),
        Make::Bytes(b"leaf count: 12\nthis is not an image\n".to_vec()),
        Failed("unrecognised content"),
    );
    add(
        "a text file (.txt)",
        "notes.txt".into(),
        Make::Bytes(b"not an image".to_vec()),
        Ignored,
    );
    add(
        "a BMP named .png (unsupported format)",
        name("BMP", next()),
        Make::Bytes({
            let mut b = b"BM".to_vec();
            b.extend([0u8; 60]);
            b
        }),
        Failed("not"),
    );
    add(
        "decompression bomb: PNG header claims 100000x100000",
        name("BOMB", next()),
        Make::Bytes(png_claiming(100_000, 100_000)),
        Failed("decompression bomb"),
    );
    add(
        "PNG header claims 20000x20000 (over max_side)",
        name("BIG", next()),
        Make::Bytes(png_claiming(20_000, 20_000)),
        Failed("exceeds the limits"),
    );
    add(
        "1x1 image",
        name("ONE", next()),
        Make::Bytes(png(DynamicImage::ImageRgb8(ImageBuffer::from_pixel(
            1,
            1,
            image::Rgb([9, 9, 9]),
        )))),
        Failed("too small"),
    );
    add(
        "100000x2 image",
        name("WIDE", next()),
        Make::Bytes(png(DynamicImage::ImageLuma8(ImageBuffer::from_pixel(
            100_000,
            2,
            image::Luma([200]),
        )))),
        Failed("too small"),
    );
    add(
        "16-bit RGB PNG",
        name("RGB16", next()),
        Make::Bytes(png(DynamicImage::ImageRgb16(ImageBuffer::from_fn(
            64,
            64,
            |x, y| {
                let p = rgb.get_pixel(x, y).0;
                image::Rgb([
                    u16::from(p[0]) * 257,
                    u16::from(p[1]) * 257,
                    u16::from(p[2]) * 257,
                ])
            },
        )))),
        Counted,
    );
    add(
        "16-bit grey PNG",
        name("GREY16", next()),
        Make::Bytes(png(DynamicImage::ImageLuma16(ImageBuffer::from_fn(
            64,
            64,
            |x, y| image::Luma([(x * 1000 + y * 7) as u16]),
        )))),
        Counted,
    );
    add(
        "8-bit grey PNG",
        name("GREY", next()),
        Make::Bytes(png(DynamicImage::ImageLuma8(ImageBuffer::from_fn(
            64,
            64,
            |x, y| image::Luma([(x * 3 + y) as u8]),
        )))),
        Counted,
    );
    add(
        "grey+alpha PNG",
        name("GA", next()),
        Make::Bytes(png(DynamicImage::ImageLumaA8(ImageBuffer::from_fn(
            64,
            64,
            |x, y| image::LumaA([(x + y) as u8, 128]),
        )))),
        Counted,
    );
    add(
        "RGBA PNG",
        name("RGBA", next()),
        Make::Bytes(png(DynamicImage::ImageRgba8(ImageBuffer::from_fn(
            64,
            64,
            |x, y| {
                let p = rgb.get_pixel(x, y).0;
                image::Rgba([p[0], p[1], p[2], (x * 4) as u8])
            },
        )))),
        Counted,
    );
    add(
        "CMYK JPEG",
        name("CMYK", next()).replace(".png", ".jpg"),
        Make::Bytes(std::fs::read(repo_root().join("daemon/tests/fixtures/cmyk.jpg")).unwrap()),
        Counted,
    );
    add(
        "RGB JPEG",
        name("JPG", next()).replace(".png", ".jpeg"),
        Make::Bytes(good_jpg.clone()),
        Counted,
    );
    add(
        "TIFF",
        name("TIF", next()).replace(".png", ".tif"),
        Make::Bytes(encode(
            DynamicImage::ImageRgb8(noise(64, 64, 5)),
            ImageFormat::Tiff,
        )),
        Counted,
    );
    add(
        "JPEG content named .png (format from content)",
        name("JASP", next()),
        Make::Bytes(encode(
            DynamicImage::ImageRgb8(noise(64, 64, 6)),
            ImageFormat::Jpeg,
        )),
        Counted,
    );
    add(
        "upper-case extension .PNG",
        name("UPPER", next()).replace(".png", ".PNG"),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 7)))),
        Counted,
    );
    add(
        "a directory named like an image",
        name("DIR", next()),
        Make::Dir,
        Ignored,
    );
    add(
        "a FIFO named like an image (never opened)",
        name("FIFO", next()),
        Make::Fifo,
        Ignored,
    );
    add(
        "a sparse 300 MiB file",
        name("HUGE", next()),
        Make::Sparse(300 << 20),
        Failed("MiB limit"),
    );
    add(
        "unreadable permissions (chmod 000)",
        name("PERM", next()),
        Make::Unreadable(png(DynamicImage::ImageRgb8(noise(64, 64, 8)))),
        // Replaced below when running as root, who can read it anyway.
        Failed("permission denied"),
    );
    add(
        "symlink pointing outside the drop directory",
        name("LINKOUT", next()),
        Make::Link(outside),
        Failed("outside the drop directory"),
    );
    let loop_name = name("LOOP", next());
    add(
        "symlink loop",
        loop_name.clone(),
        Make::Link(site.drop.join(&loop_name)),
        Failed("symbolic link loop"),
    );
    add(
        "dangling symlink",
        name("DANGLE", next()),
        Make::Link(site.tmp.path().join("no-such-file.png")),
        Failed("dangling symbolic link"),
    );
    add(
        "a name matching no pattern",
        "holiday photo.png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 9)))),
        Failed("matches none of the patterns"),
    );
    add(
        "a name with spaces",
        name("plant with spaces", next()),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 10)))),
        Counted,
    );
    add(
        "a unicode name",
        name("Sorgho-ü-高粱-🌾", next()),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 11)))),
        Counted,
    );
    add(
        "a newline in the plant id",
        name("EVIL\nforged log line", next()),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 12)))),
        Failed("control characters"),
    );
    add(
        "`..` in the name",
        name("P..1", next()),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 13)))),
        Counted,
    );
    add(
        "`..` as the whole stem (`...png`)",
        "...png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 14)))),
        // A leading dot: hidden, like a writer's temporary file.
        Ignored,
    );
    add(
        "a hidden temporary file",
        format!(".{}", name("HID", next())),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 15)))),
        Ignored,
    );
    add(
        "an impossible date (2019-02-30)",
        "D_2019-02-30_10-00-00_Vis_SV_0.png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 16)))),
        Failed("date/time is invalid"),
    );
    add(
        "an impossible time (25-61-00)",
        "D_2019-02-03_25-61-00_Vis_SV_0.png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 17)))),
        Failed("date/time is invalid"),
    );
    add(
        "an ANSI escape and a carriage return in folder names",
        format!("night\u{1b}[31m/shelf\r2/{}", name("ESC", next())),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 33)))),
        Counted,
    );
    add(
        "a capture time decades ahead (2091)",
        "D_2091-05-09_10-00-00_Vis_SV_0.png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 30)))),
        Failed("ahead of this computer's clock"),
    );
    add(
        "a capture time from a reset clock (1970)",
        "D_1970-01-01_00-00-00_Vis_SV_0.png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 31)))),
        Failed("before 2010-01-01"),
    );
    add(
        "an angle beyond any turntable (SV_99999999999999999999)",
        "D_2019-02-03_10-00-00_Vis_SV_99999999999999999999.png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 32)))),
        Failed("not an angle in degrees"),
    );
    add(
        "a plant id that looks like SQL",
        name("x'); DROP TABLE images;--", next()),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 18)))),
        Counted,
    );
    add(
        "a snapshot folder with a bad view folder",
        "2018-04-01_E_P7_2018-04-02_10-00-00_3/Vis_XX_0/0_0_0.png".into(),
        Make::Bytes(png(DynamicImage::ImageRgb8(noise(64, 64, 19)))),
        Failed("matches none of the patterns"),
    );
    c
}

fn make(site: &Site, case: &Case) -> Option<String> {
    let path = site.drop.join(&case.rel);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    match &case.make {
        Make::Bytes(b) => drop_file(&path, b, false),
        Make::Dir => std::fs::create_dir_all(&path).unwrap(),
        Make::Fifo => {
            let ok = std::process::Command::new("mkfifo").arg(&path).status();
            if !ok.is_ok_and(|s| s.success()) {
                return Some("no mkfifo".into());
            }
        }
        Make::Sparse(len) => std::fs::File::create(&path).unwrap().set_len(*len).unwrap(),
        Make::Link(target) => std::os::unix::fs::symlink(target, &path).unwrap(),
        Make::Unreadable(b) => {
            use std::os::unix::fs::PermissionsExt;
            drop_file(&path, b, false);
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o000)).unwrap();
        }
    }
    None
}

#[test]
fn bad_input_each_kind_recorded_and_service_keeps_going() {
    let site = Site::new("workers = 2\nintra_threads = 1\n", "");
    let mut all = cases(&site);
    // Root reads a chmod 000 file anyway: then the right outcome is a count.
    let probe = site.tmp.path().join("probe");
    std::fs::write(&probe, b"x").unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&probe, std::fs::Permissions::from_mode(0o000)).unwrap();
    }
    if std::fs::read(&probe).is_ok() {
        eprintln!(
            "NOTE: running as root (or with CAP_DAC_OVERRIDE): chmod 000 does not stop reads, \
             so the unreadable case is expected to be counted; as an ordinary user it must fail \
             with 'permission denied'"
        );
        for c in all.iter_mut().filter(|c| matches!(c.make, Make::Unreadable(_))) {
            c.expect = Counted;
        }
    }
    assert!(all.len() >= 30, "{} kinds", all.len());

    let mut d = site.serve();
    site.wait_running(&mut d);
    let mut skipped = Vec::new();
    for c in &all {
        if let Some(why) = make(&site, c) {
            skipped.push((c.kind, why));
        }
    }
    let recorded = all
        .iter()
        .filter(|c| c.expect != Ignored && !skipped.iter().any(|s| s.0 == c.kind))
        .count() as i64;
    site.wait_for(
        &format!("{recorded} bad-input records"),
        Duration::from_secs(120),
        || site.q("SELECT COUNT(*) FROM images") >= recorded,
    );
    // A good image after all that is still counted.
    let good = flat_name("GOOD", 28, 59, 144);
    drop_file(&site.drop.join(&good), &small_png(4242, 96), true);
    site.wait_for(
        "the good image after the bad ones",
        Duration::from_secs(60),
        || {
            site.q(&format!(
                "SELECT COUNT(*) FROM images WHERE path = '{good}' AND state = 'counted'"
            )) == 1
        },
    );
    std::thread::sleep(Duration::from_secs(3)); // one rescan: nothing is recorded twice
    assert!(d.alive(), "the service survived every kind");
    let status = site.status();
    assert!(d.term().success());

    let mut wrong = Vec::new();
    for c in &all {
        if let Some((_, why)) = skipped.iter().find(|s| s.0 == c.kind) {
            eprintln!("SKIPPED case '{}': {why}", c.kind);
            continue;
        }
        let stored = phyllo::domain::rel_path::encode(Path::new(&c.rel)).unwrap();
        let got = {
            let s = common::open(&site.db).unwrap();
            let mut st = s
                .prepare("SELECT state, error FROM images WHERE path = ?1")
                .unwrap();
            // Stored, and shown, as rel_path's lossless printable text.
            st.query_map([&stored], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, Option<String>>(1)?))
            })
            .unwrap()
            .map(Result::unwrap)
            .collect::<Vec<_>>()
        };
        let shown = stored.clone();
        let file_name =
            phyllo::domain::names::printable(Path::new(&c.rel).file_name().unwrap().to_str().unwrap());
        let ok = match (&c.expect, got.as_slice()) {
            (Ignored, []) => true,
            (Counted, [(s, None)]) => s == "counted",
            (Failed(what), [(s, Some(e))]) => {
                s == "failed"
                    && e.contains(what)
                    && (e.contains(&shown) || e.contains(&file_name))
                    && !e.contains('\n')
            }
            _ => false,
        };
        eprintln!("{:<55} {:?} -> {:?}", c.kind, c.expect, got);
        if !ok {
            wrong.push(format!("{}: expected {:?}, got {got:?}", c.kind, c.expect));
        }
    }
    assert!(wrong.is_empty(), "wrong outcomes:\n{}", wrong.join("\n"));
    // Failures reach `phyllo status` and `tail`'s feed too (a retried failure, such as
    // `permission denied` for a non-root user, is in the feed once per attempt).
    let failed = all.iter().filter(|c| matches!(c.expect, Failed(_))).count() as i64;
    assert_eq!(status["images"]["failed"].as_i64(), Some(failed), "{status}");
    assert_eq!(
        site.q("SELECT COUNT(DISTINCT path) FROM feed WHERE kind = 'failed'"),
        failed
    );
    // A plant whose every image failed has no timeline: the text lists it apart.
    let uncounted = site.q(
        "SELECT COUNT(*) FROM plants p WHERE NOT EXISTS (SELECT 1 FROM observations o WHERE o.plant_id = p.id)",
    );
    let text = String::from_utf8_lossy(&site.phyllo(&["status"]).stdout).into_owned();
    assert!(uncounted > 0, "some plant has only failed images");
    assert!(
        text.contains(&format!("plants:    {uncounted} plant")) && text.contains(" no counted image yet: "),
        "{text}"
    );
    // The SQL-looking plant id is data, nothing else: every table is still there.
    assert_eq!(
        site.q("SELECT COUNT(*) FROM plants WHERE name = 'x''); DROP TABLE images;--'"),
        1
    );
    assert_eq!(
        site.q("SELECT COUNT(*) FROM plants WHERE name = 'plant with spaces'"),
        1
    );
    assert_eq!(
        site.q("SELECT COUNT(*) FROM plants WHERE name = 'Sorgho-ü-高粱-🌾'"),
        1
    );
    assert_eq!(integrity(&site.db), "ok");
    // Control characters anywhere in a path reach neither the journal nor `tail`'s feed raw.
    assert!(
        !site.log_text().contains('\u{1b}'),
        "an ANSI escape reached the journal"
    );
    assert_eq!(
        site.q("SELECT COUNT(*) FROM feed WHERE path LIKE '%' || char(27) || '%'"),
        0
    );
    assert_eq!(
        site.q("SELECT COUNT(*) FROM images WHERE path LIKE 'night\\x1b[31m/shelf\\x0d2/%'"),
        1
    );
    // A forged log line stays on the line of the message that names it.
    assert!(
        !site.log_text().lines().any(|l| l.starts_with("forged log line")),
        "a newline in a file name forged a log line"
    );
}

/// Runs `phyllo serve` with a config that must be refused; returns stderr.
fn serve_refused(cfg_text: &str) -> String {
    let site = Site::new("", "");
    std::fs::write(
        &site.cfg,
        cfg_text.replace("$DIR", site.tmp.path().to_str().unwrap()),
    )
    .unwrap();
    let out = site.phyllo(&["serve"]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "must refuse to start: {err}");
    assert!(!site.db.exists(), "nothing written when the start is refused");
    err
}

#[test]
fn model_not_onnx_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.onnx");
    std::fs::write(&model, "this is not a model\n").unwrap();
    let err = serve_refused(&format!(
        "drop_dir = \"$DIR/drop\"\ndatabase = \"$DIR/state/phyllo.sqlite\"\n[inference]\nmodel = {model:?}\n"
    ));
    assert!(err.contains("model.onnx"), "{err}");
}

#[test]
fn model_with_wrong_contract_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("wrong-contract.onnx");
    // The shipped model with its contract-version metadata key renamed (same length).
    let mut bytes = std::fs::read(common::model()).unwrap();
    let key = b"phyllo.contract_version";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("metadata key");
    bytes[at + key.len() - 1] = b'X';
    std::fs::write(&model, bytes).unwrap();
    let err = serve_refused(&format!(
        "drop_dir = \"$DIR/drop\"\ndatabase = \"$DIR/state/phyllo.sqlite\"\n[inference]\nmodel = {model:?}\n"
    ));
    assert!(
        err.contains("wrong-contract.onnx") && err.contains("contract"),
        "{err}"
    );
}

#[test]
fn model_missing_is_refused_at_start() {
    let err = serve_refused(
        "drop_dir = \"$DIR/drop\"\ndatabase = \"$DIR/state/phyllo.sqlite\"\n[inference]\nmodel = \"$DIR/nope.onnx\"\n",
    );
    assert!(err.contains("nope.onnx"), "{err}");
}

#[test]
fn config_unknown_key_is_refused() {
    let err = serve_refused(
        "drop_dir = \"$DIR/drop\"\ndatabase = \"$DIR/state/phyllo.sqlite\"\n[watch]\nstable_sec = 3\n",
    );
    assert!(err.contains("stable_sec") && err.contains("phyllo.toml"), "{err}");
}

#[test]
fn config_unknown_section_is_refused() {
    let err = serve_refused("drop_dir = \"$DIR/drop\"\ndatabase = \"$DIR/state/phyllo.sqlite\"\n[wacth]\n");
    assert!(err.contains("wacth"), "{err}");
}

#[test]
fn config_wrong_type_is_refused() {
    let err = serve_refused(
        "drop_dir = \"$DIR/drop\"\ndatabase = \"$DIR/state/phyllo.sqlite\"\n[inference]\nworkers = \"two\"\n",
    );
    assert!(err.contains("workers") && err.contains("phyllo.toml"), "{err}");
}

#[test]
fn config_negative_number_is_refused() {
    let err = serve_refused(
        "drop_dir = \"$DIR/drop\"\ndatabase = \"$DIR/state/phyllo.sqlite\"\n[inference]\nqueue_capacity = -1\n",
    );
    assert!(err.contains("queue_capacity"), "{err}");
}

#[test]
fn config_missing_required_key_is_refused() {
    let err = serve_refused("drop_dir = \"$DIR/drop\"\n");
    assert!(err.contains("database"), "{err}");
}

#[test]
fn config_not_toml_is_refused() {
    let err = serve_refused("drop_dir: /srv/drop\ndatabase: x\n");
    assert!(err.contains("phyllo.toml"), "{err}");
}
