//! `normalfit convert --mips` (issue 33): every level the command line
//! writes, in a DDS without blocks and in PNG levels, against the shared
//! reference fit (tests/common/reference.rs) of the heights box-filtered
//! here; the average chain of a normal map against the renormalised mean
//! written here; the level count of a 300 × 7 map; the roughness chain of
//! two alternating slopes and of a constant base against Toksvig's formula;
//! and the errors, one line naming the file, exit 2.

use std::fs;
use std::io::Cursor;
use std::path::{Path, PathBuf};

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

/// The inputs the refusals below start from: a 16 × 8 height map
/// (`h.png`) and a normal map (`map.png`) in `dir`.
fn height_and_normal_maps(dir: &Path) -> (PathBuf, PathBuf) {
    let (w, h) = (16, 8);
    let heights_png = dir.join("h.png");
    write_heights(&heights_png, &heights(w, h), (w, h));
    let map = dir.join("map.png");
    write_normal_map(&map, &bumpy_normals(w, h).1, (w, h));
    (heights_png, map)
}

/// Errors: exit 2, one line on standard error naming the file at fault.
#[test]
fn bad_requests_exit_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (heights_png, map) = height_and_normal_maps(dir.path());
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

/// The fourth plane of a DDS or KTX2 level's RGBA texels, `per` bytes a
/// texel, read by `value`.
fn alpha_of(bytes: &[u8], per: usize, value: impl Fn(&[u8]) -> f64) -> Vec<f64> {
    bytes.chunks_exact(per).map(|t| value(&t[per / 4 * 3..])).collect()
}

/// A KTX2 file's levels (the finest first), by its level index (Khronos
/// KTX 2.0: 80 bytes of header and index, then 24 bytes a level: offset,
/// length, uncompressed length), and its `vkFormat`.
fn ktx2_levels(path: &Path) -> (u32, Vec<Vec<u8>>) {
    let bytes = fs::read(path).unwrap();
    assert_eq!(&bytes[..12], b"\xABKTX 20\xBB\r\n\x1A\n");
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let u64_at = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let count = u32_at(40) as usize;
    let levels = (0..count).map(|k| bytes[u64_at(80 + 24 * k)..][..u64_at(88 + 24 * k)].to_vec()).collect();
    (u32_at(12), levels)
}

/// `--alpha height` with `--mips`: each level's alpha holds that level's
/// heights, the box filter of the finest (contract units: 16-bit samples
/// over 65535), in a DDS without blocks (RGBA8), a KTX2 of half floats
/// (RGBA16F) and 16-bit PNG levels; level 0's alpha is the single image's
/// `--alpha height` bit for bit.
#[test]
fn an_alpha_of_heights_holds_each_levels_heights() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37, 20);
    let samples = heights(w, h);
    let input = dir.path().join("h.png");
    write_heights(&input, &samples, (w, h));
    let (dds, ktx2, png, single) =
        (dir.path().join("n.dds"), dir.path().join("n.ktx2"), dir.path().join("n.png"), dir.path().join("one.png"));
    let common = ["--mips", "--alpha", "height", "--border", "clamp"];
    succeeds(&[&["convert", s(&input), "-o", s(&dds), "--compress", "none"], &common[..]].concat());
    succeeds(&[&["convert", s(&input), "-o", s(&ktx2), "--compress", "none", "--bits", "16"], &common[..]].concat());
    succeeds(&[&["convert", s(&input), "-o", s(&png), "--bits", "16"], &common[..]].concat());
    succeeds(&["convert", s(&input), "-o", s(&single), "--bits", "16", "--alpha", "height", "--border", "clamp"]);

    let values: Vec<f64> = samples.iter().map(|&v| f64::from(v) / 65535.0).collect();
    let sizes = level_sizes(w, h);
    let (count, texture) = dds_levels(&dds);
    assert_eq!(count as usize, sizes.len());
    let (format, halves) = ktx2_levels(&ktx2);
    assert_eq!((format, halves.len()), (97, sizes.len()), "R16G16B16A16_SFLOAT, every level");
    let mut offset = 0;
    for (k, &(lw, lh)) in sizes.iter().enumerate() {
        let want = if k == 0 { values.clone() } else { box_filter(&values, (w, h), (lw, lh)) };
        let bytes = &texture[offset..offset + lw * lh * 4];
        offset += lw * lh * 4;
        let in_dds = alpha_of(bytes, 4, |a| f64::from(a[0]));
        let in_ktx2 = alpha_of(&halves[k], 8, |a| f64::from(half::f16::from_le_bytes([a[0], a[1]]).to_f32()));
        let level_png = if k == 0 { png.clone() } else { dir.path().join(format!("n_mip{k}.png")) };
        let (pw, ph, a) = planes(&level_png, &["A"]);
        assert_eq!((pw, ph, in_dds.len(), in_ktx2.len()), (lw, lh, lw * lh, lw * lh), "level {k}");
        for (t, &v) in want.iter().enumerate() {
            let at = format!("level {k} ({lw} × {lh}) texel {t}");
            assert!((in_dds[t] - 255.0 * v).abs() <= 0.5 + 1e-6, "DDS {at}: {} for {v}", in_dds[t]);
            assert!((in_ktx2[t] - v).abs() <= v * 2f64.powi(-11) + 1e-7, "KTX2 {at}: {} for {v}", in_ktx2[t]);
            assert!((f64::from(a[0][t]) - v).abs() <= 0.6 / 65535.0, "PNG {at}: {} for {v}", a[0][t]);
        }
    }
    // Level 0 as the single image holds it, bit for bit.
    let level0 = normalfit::io::read_path(&png, &Default::default()).unwrap();
    let one = normalfit::io::read_path(&single, &Default::default()).unwrap();
    assert_eq!(level0.plane("A").unwrap().data, one.plane("A").unwrap().data);
    assert_eq!(level0.plane("R").unwrap().data, one.plane("R").unwrap().data);
}

/// An alpha of heights where there are none, or in a texture without an
/// alpha (BC5, the default): exit 2, one line naming the file, nothing
/// written.
#[test]
fn an_alpha_of_heights_needs_heights_and_a_texture_with_an_alpha() {
    let dir = tempfile::tempdir().unwrap();
    let (heights_png, map) = height_and_normal_maps(dir.path());
    let (dds, png) = (dir.path().join("out.dds"), dir.path().join("out.png"));
    let cases: [(Vec<&str>, &Path, &str); 3] = [
        (vec!["convert", s(&heights_png), "-o", s(&dds), "--mips", "--alpha", "height"], &dds, "bc7 or none"),
        (
            vec!["convert", s(&heights_png), "-o", s(&dds), "--mips", "--alpha", "height", "--compress", "bc5"],
            &dds,
            "no alpha",
        ),
        (vec!["convert", s(&map), "-o", s(&png), "--mips", "--alpha", "height"], &map, "needs a height map"),
    ];
    for (args, named, says) in cases {
        let r = run(&args);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
        assert!(lines[0].contains(s(named)) && lines[0].contains(says), "{args:?}: {stderr}");
    }
    assert!(!dds.exists() && !png.exists());
}

/// The names of the files in `dir`, sorted, and each one's bytes.
fn contents(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), fs::read(&p).unwrap()))
        .collect();
    files.sort();
    files
}

/// Every file of a chain goes through `--overwrite`: a level that exists
/// (not level 0) is kept under `never` and `older` (newer than the input),
/// the command exits 2 with one line naming it and writes nothing; a chain
/// whose every file exists is skipped; with the default every file is
/// replaced.
#[test]
fn every_file_of_a_chain_goes_through_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (16, 8);
    let input = dir.path().join("h.png");
    write_heights(&input, &heights(w, h), (w, h));
    let out = dir.path().join("x.png");
    let level1 = dir.path().join("x_mip1.png");
    let rough2 = dir.path().join("x_roughness_mip2.png");
    for (kept, extra) in [(&level1, &[][..]), (&rough2, &["--roughness"][..])] {
        for policy in ["never", "older"] {
            fs::write(kept, b"kept").unwrap();
            // Newer than the input: `older` keeps it too.
            let later = std::time::SystemTime::now() + std::time::Duration::from_secs(3600);
            fs::File::options().write(true).open(kept).unwrap().set_modified(later).unwrap();
            let before = contents(dir.path());
            let args = [&["convert", s(&input), "-o", s(&out), "--mips", "--overwrite", policy], extra].concat();
            let r = run(&args);
            let stderr = String::from_utf8_lossy(&r.stderr);
            assert_eq!(r.status.code(), Some(2), "{args:?}: {stderr}");
            assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
            assert!(stderr.contains(s(kept)) && stderr.contains("exists and is kept"), "{args:?}: {stderr}");
            assert_eq!(contents(dir.path()), before, "{args:?}: nothing written");
            fs::remove_file(kept).unwrap();
        }
    }
    // Every file there: skipped, untouched.
    succeeds(&["convert", s(&input), "-o", s(&out), "--mips", "--roughness"]);
    let chain = contents(dir.path());
    assert_eq!(chain.len(), 1 + 2 * level_sizes(w, h).len());
    let r = run(&["convert", s(&input), "-o", s(&out), "--mips", "--roughness", "--overwrite", "never"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(contents(dir.path()), chain);
    // The default replaces them all.
    fs::write(&level1, b"old").unwrap();
    succeeds(&["convert", s(&input), "-o", s(&out), "--mips", "--roughness"]);
    assert_eq!(contents(dir.path()), chain);
}

/// No file of a chain replaces an input: an input named as a level or a
/// roughness output of its own chain, or of another input's in a batch,
/// is refused in one line (exit 2) and nothing of that chain is written;
/// the batch goes on. The library refuses it too, without the command
/// line's claims.
#[test]
fn no_file_of_a_chain_replaces_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (16, 8);
    let samples = heights(w, h);
    // Its own chain: g.png's level 1 is the input.
    let own = dir.path().join("g_mip1.png");
    write_heights(&own, &samples, (w, h));
    let out = dir.path().join("g.png");
    let r = run(&["convert", s(&own), "-o", s(&out), "--mips"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!((r.status.code(), stderr.lines().count()), (Some(2), 1), "{stderr}");
    assert!(stderr.contains("g_mip1.png") && stderr.contains("never writes over an input"), "{stderr}");
    assert!(!out.exists());
    let roughness = dir.path().join("r_roughness.png");
    write_heights(&roughness, &samples, (w, h));
    let r = run(&["convert", s(&roughness), "-o", s(&dir.path().join("r.png")), "--mips", "--roughness"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("r_roughness.png") && stderr.contains("never writes over an input"), "{stderr}");
    assert!(!dir.path().join("r.png").exists());
    assert_eq!(fs::read(&own).unwrap(), fs::read(&roughness).unwrap(), "the inputs are as they were");

    // A batch, outputs beside the inputs: a.png's level 2 is b's input.
    let batch = dir.path().join("batch");
    fs::create_dir(&batch).unwrap();
    let (a, b) = (batch.join("a.png"), batch.join("a_normal_mip2.png"));
    write_heights(&a, &samples, (w, h));
    write_heights(&b, &samples, (w, h));
    let b_bytes = fs::read(&b).unwrap();
    let r = run(&["convert", s(&a), s(&b), "--mips"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(stderr.lines().any(|l| l.contains("a_normal_mip2.png") && l.contains("never writes over an input")));
    assert_eq!(fs::read(&b).unwrap(), b_bytes);
    assert!(!batch.join("a_normal.png").exists() && !batch.join("a_normal_mip1.png").exists());
    assert!(batch.join("a_normal_mip2_normal_mip3.png").exists(), "the other input is converted");

    // The library: the input itself, and the batch's inputs it is given.
    use normalfit::convert::{Conversion, MipChoice};
    let mips = Conversion::new().with_mips(Some(MipChoice::Fit));
    let err = mips.convert_file(&own, &out).unwrap_err();
    assert!(err.to_string().contains("never writes over an input"), "{err}");
    let other = dir.path().join("c.png");
    write_heights(&other, &samples, (w, h));
    let inputs = std::sync::Arc::new(normalfit::io::Inputs::of([&other, &own]));
    let err = mips.clone().with_inputs(inputs).convert_file(&other, &dir.path().join("g.png")).unwrap_err();
    assert!(err.to_string().contains("g_mip1.png is one of the inputs"), "{err}");
    assert!(!out.exists());
}

/// A folder searched again skips the chains an earlier run wrote beside
/// its images (`<stem>_normal_mip<k>`, `_roughness`), as it skips their
/// normal maps; a file of it whose chain cannot be written does not stop
/// the others.
#[test]
fn a_folder_skips_earlier_chains_and_goes_on_past_a_kept_level() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (16, 8);
    for name in ["a.png", "b.png"] {
        write_heights(&dir.path().join(name), &heights(w, h), (w, h));
    }
    let kept = dir.path().join("a_normal_mip3.png");
    write_heights(&kept, &heights(2, 1), (2, 1));
    let later = std::time::SystemTime::now() + std::time::Duration::from_secs(3600);
    fs::File::options().write(true).open(&kept).unwrap().set_modified(later).unwrap();
    let r = run(&["convert", s(dir.path()), "--mips", "--roughness", "--border", "clamp", "--overwrite", "never"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !common::cli::is_summary(l)).collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].contains("a_normal_mip3.png") && lines[0].contains("exists and is kept"), "{stderr}");
    assert!(dir.path().join("b_normal_mip3.png").exists() && dir.path().join("b_normal_roughness.png").exists());
    assert!(!dir.path().join("a_normal.png").exists());
    // Again, every file replaced: the chains of the first run are not inputs.
    let r = run(&["convert", s(dir.path()), "--mips", "--roughness", "--border", "clamp"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{stderr}");
    let summary = stderr.lines().find_map(common::cli::summary_counts).expect("a summary line");
    assert_eq!(summary.1, 2, "two images converted: {stderr}");
}
