//! The generated samples keep their promise: `bricks` and `rock` tile,
//! `terrain` does not (it is there to make the tiling check fail).
//!
//! The measure is independent of the library's tiling module. For each
//! pair of neighbouring columns, take the mean absolute height step down
//! the rows; the wrap seam is the pair (last column, first column). If the
//! texture tiles, the seam is just another column pair: its step is like
//! the interior's mean and no larger than the worst interior pair. If it
//! does not, the seam's step is many times the interior's. Rows likewise.
//!
//! Measured on the committed files (seam / interior mean):
//! bricks 0.36 (x), 0.11 (y); rock 1.54, 1.34 (a crack runs near x = 0;
//! the worst interior column pair is 1.65); terrain 31, 16.

use std::path::PathBuf;

/// Heights of `samples/<name>.png` as 16-bit values, with the size.
fn load(name: &str) -> (Vec<f64>, usize, usize) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("samples").join(format!("{name}.png"));
    let img = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (run `cargo run --release --example make_samples`)", path.display()))
        .into_luma16();
    let (w, h) = (img.width() as usize, img.height() as usize);
    (img.into_raw().into_iter().map(f64::from).collect(), w, h)
}

/// Seam statistics along one axis, in units of the mean interior step.
#[derive(Debug)]
struct Seam {
    /// The wrap pair's mean step.
    seam: f64,
    /// The largest interior pair's mean step.
    worst_interior: f64,
}

/// `lines` lines of `len` texels; `step(k, i)` is the absolute step between
/// line k and line k + 1 (wrapping) at position i along them.
fn seam(lines: usize, len: usize, step: impl Fn(usize, usize) -> f64) -> Seam {
    let pair: Vec<f64> = (0..lines).map(|k| (0..len).map(|i| step(k, i)).sum::<f64>() / len as f64).collect();
    let interior = &pair[..lines - 1];
    let mean = interior.iter().sum::<f64>() / interior.len() as f64;
    let worst = interior.iter().copied().fold(0.0, f64::max);
    Seam { seam: pair[lines - 1] / mean, worst_interior: worst / mean }
}

/// (columns, rows) seam statistics of a sample.
fn seams(name: &str) -> (Seam, Seam) {
    let (v, w, h) = load(name);
    let at = |x: usize, y: usize| v[y * w + x];
    let x = seam(w, h, |k, y| (at((k + 1) % w, y) - at(k, y)).abs());
    let y = seam(h, w, |k, x| (at(x, (k + 1) % h) - at(x, k)).abs());
    eprintln!("{name}: columns {x:?}, rows {y:?}");
    (x, y)
}

fn assert_tiles(name: &str) {
    let (x, y) = seams(name);
    for (axis, s) in [("x", x), ("y", y)] {
        assert!(s.seam < 2.0, "{name} {axis}: seam step {:.2}× the interior mean", s.seam);
        assert!(s.seam <= s.worst_interior, "{name} {axis}: seam worse than every interior pair: {s:?}");
    }
}

#[test]
fn bricks_tile_on_both_axes() {
    assert_tiles("bricks");
}

#[test]
fn rock_tiles_on_both_axes() {
    assert_tiles("rock");
}

#[test]
fn terrain_does_not_tile() {
    let (x, y) = seams("terrain");
    for (axis, s) in [("x", x), ("y", y)] {
        assert!(s.seam > 8.0, "terrain {axis}: seam step only {:.2}× the interior mean", s.seam);
        assert!(s.seam > 3.0 * s.worst_interior, "terrain {axis}: {s:?}");
    }
}

/// The README's commands, run on the shipped samples, give exactly the
/// shipped normal maps: the pictures show what the tool does.
#[test]
fn readme_commands_reproduce_the_shipped_normal_maps() {
    let samples = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("samples");
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str]); 3] =
        [("bricks", &["-s", "8"]), ("rock", &["-s", "16"]), ("terrain", &["-s", "40", "-n", "5", "--border", "clamp"])];
    for (name, args) in cases {
        let out = dir.path().join(format!("{name}.png"));
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_normalfit"))
            .arg("convert")
            .arg(samples.join(format!("{name}.png")))
            .args(args)
            .arg("-o")
            .arg(&out)
            .status()
            .unwrap();
        assert!(status.success(), "{name}");
        let got = image::open(&out).unwrap();
        assert_eq!(got.color(), image::ColorType::Rgb16, "{name}: a 16-bit height map gives a 16-bit normal map");
        let want = image::open(samples.join(format!("{name}_normal.png"))).unwrap().to_rgb8();
        // The shipped maps are 8-bit; the 16-bit output rounds to the same
        // 8-bit values within one step (double rounding).
        let got = got.to_rgb16();
        for (k, (g, w)) in got.pixels().zip(want.pixels()).enumerate() {
            for c in 0..3 {
                let g8 = f64::from(g.0[c]) * 255.0 / 65535.0;
                assert!((g8 - f64::from(w.0[c])).abs() <= 0.51, "{name} texel {k} channel {c}: {g8} vs {}", w.0[c]);
            }
        }
    }
}

/// The README's gallery starts from the samples at half size in 8 bits:
/// each texel the mean of a 2×2 block of the sample, rounded to 8 bits.
#[test]
fn gallery_height_maps_are_the_samples_at_half_size() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    for name in ["bricks", "rock", "terrain"] {
        let (sample, w, h) = load(name);
        let small = image::open(root.join("docs/gallery").join(format!("{name}.png"))).unwrap();
        assert_eq!(small.color(), image::ColorType::L8, "{name}");
        let small = small.into_luma8();
        assert_eq!((small.width() as usize, small.height() as usize), (w / 2, h / 2), "{name}");
        for (x, y, p) in small.enumerate_pixels() {
            let (x, y) = (x as usize * 2, y as usize * 2);
            let mean =
                (sample[y * w + x] + sample[y * w + x + 1] + sample[(y + 1) * w + x] + sample[(y + 1) * w + x + 1])
                    / 4.0;
            assert_eq!(f64::from(p.0[0]), (mean / 257.0).round(), "{name} ({x}, {y})");
        }
    }
}
