//! `normalfit convert --mips` (issue 33): every level the command line
//! writes, in a DDS without blocks and in PNG levels, against the shared
//! reference fit (tests/common/reference.rs) of the heights box-filtered
//! here; the average chain of a normal map against the renormalised mean
//! written here; the level count of a 300 × 7 map; the roughness chain of
//! two alternating slopes and of a constant base against Toksvig's formula;
//! and the errors, one line naming the file, exit 2.

use std::fs;
use std::io::Cursor;
use std::path::Path;

use crate::common;

use common::cli::{run, s};
use common::mips::{box_filter, heights};
use common::reference;
use normalfit::io::{Encoding, PngDepth, PngOptions};
use normalfit::mips::level_sizes;
use normalfit::{Border, Borders, Options, Spacing, Strength, Units};

/// Writes 16-bit gray heights as a PNG.
fn write_heights(path: &Path, samples: &[u16], (w, h): (usize, usize)) {
    let mut png = Vec::new();
    let encoding: Encoding = PngOptions::new(PngDepth::Sixteen).into();
    normalfit::io::encode_gray(samples, w, h, &encoding, Cursor::new(&mut png)).unwrap();
    fs::write(path, png).unwrap();
}

/// Writes 16-bit RGB texels as a PNG normal map.
fn write_normal_map(path: &Path, texels: &[[u16; 3]], (w, h): (usize, usize)) {
    let mut png = Vec::new();
    normalfit::io::encode_normals(texels, None, w, h, &Encoding::png16(), Cursor::new(&mut png)).unwrap();
    fs::write(path, png).unwrap();
}

/// Unit normals with detail in both directions, and their 16-bit texels.
fn bumpy_normals(w: usize, h: usize) -> (Vec<[f64; 3]>, Vec<[u16; 3]>) {
    let normals: Vec<[f64; 3]> = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64, (k / w) as f64);
            reference::unit([0.6 * (x * 0.9).sin(), 0.4 * (y * 1.3 + x * 0.2).cos(), 1.0])
        })
        .collect();
    let texels = normals.iter().map(|n| n.map(|c| ((c + 1.0) / 2.0 * 65535.0).round() as u16)).collect();
    (normals, texels)
}

/// A file's planes as f32 in [0, 1] (integers over their maximum), by
/// name.
fn planes(path: &Path, names: &[&str]) -> (usize, usize, Vec<Vec<f32>>) {
    let raster = normalfit::io::read_path(path, &Default::default()).unwrap();
    let planes = names.iter().map(|n| raster.plane(n).unwrap().data.to_f32().unwrap()).collect();
    (raster.width, raster.height, planes)
}

/// The levels of a DDS file with the DX10 header: its level count, and
/// the bytes that follow the 148 header bytes.
fn dds_levels(path: &Path) -> (u32, Vec<u8>) {
    let bytes = fs::read(path).unwrap();
    assert_eq!(&bytes[..4], b"DDS ");
    let count = u32::from_le_bytes(bytes[28..32].try_into().unwrap());
    (count, bytes[148..].to_vec())
}

fn succeeds(args: &[&str]) {
    let r = run(args);
    assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
}

/// `convert --mips fit`, to a DDS without blocks (RGBA8) and to 16-bit PNG
/// levels: level k is the reference fit of the heights box-filtered to its
/// size, its texels spaced by their footprint, with the finest gain.
#[test]
fn fitted_levels_in_dds_and_png_are_the_reference_fit_of_the_filtered_heights() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37, 20);
    let samples = heights(w, h);
    let input = dir.path().join("h.png");
    write_heights(&input, &samples, (w, h));
    let (dds, png) = (dir.path().join("n.dds"), dir.path().join("n.png"));
    let common = ["--mips", "fit", "-n", "5", "--border", "clamp", "-s", "6"];
    succeeds(&[&["convert", s(&input), "-o", s(&dds), "--compress", "none"], &common[..]].concat());
    succeeds(&[&["convert", s(&input), "-o", s(&png), "--bits", "16"], &common[..]].concat());

    let opts =
        Options::new().with_patch(5).with_borders(Borders::both(Border::Clamp)).with_strength(Strength::Scale(6.0));
    let values: Vec<f64> = samples.iter().map(|&v| f64::from(v) / 65535.0).collect();
    let gain = reference::gain(&opts, w);
    let sizes = level_sizes(w, h);
    let (count, texture) = dds_levels(&dds);
    assert_eq!(count as usize, sizes.len());
    assert_eq!(texture.len(), sizes.iter().map(|(a, b)| a * b * 4).sum::<usize>());
    let mut offset = 0;
    for (k, &(lw, lh)) in sizes.iter().enumerate() {
        let want = if k == 0 {
            reference::normal_map(&values, w, h, &opts)
        } else {
            let reduced = box_filter(&values, (w, h), (lw, lh));
            let spacing = Spacing::Uniform { x: w as f64 / lw as f64, y: h as f64 / lh as f64 };
            let level_opts = opts.clone().with_units(Units::Map(spacing)).with_strength(Strength::Scale(gain));
            reference::normal_map(&reduced, lw, lh, &level_opts)
        };
        let level_png = if k == 0 { png.clone() } else { dir.path().join(format!("n_mip{k}.png")) };
        let (pw, ph, rgb) = planes(&level_png, &["R", "G", "B"]);
        assert_eq!((pw, ph), (lw, lh), "level {k}");
        for (i, n) in want.iter().enumerate() {
            for c in 0..3 {
                let code8 = f64::from(texture[offset + 4 * i + c]);
                let at = format!("level {k} texel {i} component {c}");
                assert!((code8 - (n[c] + 1.0) * 127.5).abs() <= 0.5 + 1e-3, "DDS {at}: {code8} for {}", n[c]);
                let stored = f64::from(rgb[c][i]);
                assert!((stored - (n[c] + 1.0) / 2.0).abs() <= 0.6 / 65535.0, "PNG {at}: {stored} for {}", n[c]);
            }
            assert_eq!(texture[offset + 4 * i + 3], 255);
        }
        offset += lw * lh * 4;
    }
    assert!(!dir.path().join(format!("n_mip{}.png", sizes.len())).exists());
}

/// A normal map's chain (`--mips`, detected): each level the renormalised
/// mean of the finer level's normals.
#[test]
fn a_normal_maps_levels_are_the_renormalised_means_of_the_finer_ones() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (24, 10);
    let (_, texels) = bumpy_normals(w, h);
    let input = dir.path().join("map.png");
    write_normal_map(&input, &texels, (w, h));
    let out = dir.path().join("avg.png");
    succeeds(&["convert", s(&input), "-o", s(&out), "--mips", "--bits", "16"]);
    // The finest level as the file stores it, then each level from the one
    // before.
    let mut level: Vec<[f64; 3]> = texels.iter().map(|t| t.map(|c| 2.0 * f64::from(c) / 65535.0 - 1.0)).collect();
    for (k, pair) in level_sizes(w, h).windows(2).enumerate() {
        let ((fw, fh), (lw, lh)) = (pair[0], pair[1]);
        let means: Vec<Vec<f64>> =
            (0..3).map(|c| box_filter(&level.iter().map(|n| n[c]).collect::<Vec<_>>(), (fw, fh), (lw, lh))).collect();
        level = (0..lw * lh).map(|i| reference::unit([means[0][i], means[1][i], means[2][i]])).collect();
        let (_, _, rgb) = planes(&dir.path().join(format!("avg_mip{}.png", k + 1)), &["R", "G", "B"]);
        for (i, n) in level.iter().enumerate() {
            for c in 0..3 {
                let stored = f64::from(rgb[c][i]);
                assert!((stored - (n[c] + 1.0) / 2.0).abs() <= 0.6 / 65535.0, "level {} texel {i}: {stored}", k + 1);
            }
        }
    }
}

/// 300 × 7: nine levels, in the texture and as files.
#[test]
fn three_hundred_by_seven_has_nine_levels() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("strip.png");
    write_heights(&input, &heights(300, 7), (300, 7));
    let (ktx, dds, png) = (dir.path().join("s.ktx2"), dir.path().join("s.dds"), dir.path().join("s.png"));
    succeeds(&["convert", s(&input), "-o", s(&dds), "--mips"]);
    succeeds(&["convert", s(&input), "-o", s(&ktx), "--mips"]);
    succeeds(&["convert", s(&input), "-o", s(&png), "--mips"]);
    assert_eq!(dds_levels(&dds).0, 9);
    // KTX2's levelCount: after the identifier (12), vkFormat, typeSize,
    // width, height, depth, layerCount, faceCount.
    let bytes = fs::read(&ktx).unwrap();
    assert_eq!(u32::from_le_bytes(bytes[40..44].try_into().unwrap()), 9);
    for k in 1..9 {
        assert!(dir.path().join(format!("s_mip{k}.png")).exists(), "level {k}");
    }
    assert!(!dir.path().join("s_mip9.png").exists());
    // Without --mips a texture holds level 0 alone.
    let single = dir.path().join("one.dds");
    succeeds(&["convert", s(&input), "-o", s(&single)]);
    assert_eq!(dds_levels(&single).0, 1);
}

/// Normals alternating texel by texel between slopes +s and −s along x:
/// every level above the finest has |n̄| = 1 / √(1 + s²), so σ² = √(1 +
/// s²) − 1, and r = (r_base⁴ + σ²)^¼; level 0 holds r_base.
#[test]
fn the_roughness_of_alternating_slopes_follows_toksvig_at_every_level() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h, slope) = (32, 8, 0.5f64);
    let texels: Vec<[u16; 3]> = (0..w * h)
        .map(|k| {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            reference::unit([sign * slope, 0.0, 1.0]).map(|c| ((c + 1.0) / 2.0 * 65535.0).round() as u16)
        })
        .collect();
    let input = dir.path().join("zigzag.png");
    write_normal_map(&input, &texels, (w, h));
    // The stored normals, as the file gives them back: their mean's length.
    let stored: Vec<[f64; 3]> = texels[..2].iter().map(|t| t.map(|c| 2.0 * f64::from(c) / 65535.0 - 1.0)).collect();
    let length = |n: [f64; 3]| (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let mean = [0, 1, 2].map(|c| (stored[0][c] + stored[1][c]) / 2.0);
    // The lengths relative to the stored normals' own (|n| of a 16-bit
    // normal is 1 within 2⁻¹⁶): σ² from the formula at slope s.
    let formula = (1.0 + slope * slope).sqrt() - 1.0;
    let from_file = (1.0 - length(mean)) / length(mean);
    assert!((formula - from_file).abs() < 1e-4, "{formula} {from_file}");

    let base_value = 0.4f64;
    let base = dir.path().join("base.png");
    write_heights(&base, &vec![(base_value * 65535.0).round() as u16; w * h], (w, h));
    let base_value = (base_value * 65535.0).round() / 65535.0;
    for (name, extra, r_base) in [("plain", None, 0.0), ("based", Some(&base), base_value)] {
        let out = dir.path().join(format!("{name}.png"));
        let mut args = vec!["convert", s(&input), "-o", s(&out), "--mips", "average", "--roughness"];
        if let Some(b) = extra {
            args.extend(["--roughness-base", s(b)]);
        }
        succeeds(&args);
        for (k, &(lw, lh)) in level_sizes(w, h).iter().enumerate() {
            let file = match k {
                0 => dir.path().join(format!("{name}_roughness.png")),
                k => dir.path().join(format!("{name}_roughness_mip{k}.png")),
            };
            let (gw, gh, gray) = planes(&file, &["Y"]);
            assert_eq!((gw, gh), (lw, lh));
            let variance = if k == 0 { 0.0 } else { from_file };
            let want = (r_base.powi(4) + variance).min(1.0).powf(0.25);
            for (i, &r) in gray[0].iter().enumerate() {
                assert!((f64::from(r) - want).abs() <= 1e-4, "{name} level {k} texel {i}: {r}, want {want}");
            }
        }
    }
}

/// Errors: exit 2, one line on standard error naming the file at fault.
#[test]
fn bad_requests_exit_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (16, 8);
    let heights_png = dir.path().join("h.png");
    write_heights(&heights_png, &heights(w, h), (w, h));
    let map = dir.path().join("map.png");
    write_normal_map(&map, &bumpy_normals(w, h).1, (w, h));
    let small = dir.path().join("small.png");
    write_heights(&small, &heights(8, 8), (8, 8));
    let out = dir.path().join("out.png");
    let cases: [(Vec<&str>, &Path); 3] = [
        (vec!["convert", s(&map), "-o", s(&out), "--mips", "fit"], &map),
        (
            vec![
                "convert",
                s(&heights_png),
                "-o",
                s(&out),
                "--mips",
                "--border",
                "clamp",
                "--roughness-base",
                s(&small),
            ],
            &small,
        ),
        (vec!["convert", s(&heights_png), "-o", s(&out), "--compress", "bc5"], &out),
    ];
    for (args, named) in cases {
        let r = run(&args);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
        assert!(lines[0].contains(s(named)), "{args:?}: {stderr}");
    }
    assert!(!out.exists());
}

/// A batch goes on past a file whose chain cannot be made.
#[test]
fn a_bad_file_does_not_stop_a_batch() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (16, 8);
    let good = dir.path().join("a.png");
    write_heights(&good, &heights(w, h), (w, h));
    let map = dir.path().join("b.png");
    write_normal_map(&map, &bumpy_normals(w, h).1, (w, h));
    let out = dir.path().join("out");
    let r = run(&["convert", s(&map), s(&good), "-o", s(&out), "--mips", "fit", "--format", "dds"]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.join("a_normal.dds").exists());
    assert!(!out.join("b_normal.dds").exists());
}
