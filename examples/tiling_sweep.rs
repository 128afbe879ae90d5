//! The sweep behind the tiling check's default threshold: many generated
//! images that must tile and many that must not, scored by
//! `normalfit::tiling::check`; prints, per group and per size, the highest
//! score of a tileable axis and the lowest of a non-tiling one, and how
//! many axes the threshold judges wrong.
//!
//! `cargo run --release --example tiling_sweep [-- --per N] [-- --dump DIR]`
//!
//! The groups (each at 64², 96², 128², 256², 512², 512×256 and 256×512):
//!
//! * periodic value noise, 1 to 3 octaves of 2 to 8 cells (tiles), and
//!   windows cut off-period from a noise three times as large (does not);
//! * structured textures, exactly periodic (tiles): bricks, planks, tiles
//!   and cables, axis-aligned, rotated by atan(1/2) or atan(1/3), or
//!   sheared (lines at atan(k·H/W)), with a fine surface grain and noise;
//! * structured photos (does not tile): the same scenes seen at 3° to 43°
//!   either way, with keystone, zoom 0.5 to 2, uneven light or none, grain
//!   and sensor noise, 8-bit, gray or RGB.
//!
//! `--per N` draws N images of each kind per size (default 8); `--sizes
//! 1024x1024,2048x1024` other sizes than these; `--dump DIR`
//! writes each wrongly judged image, shifted by half so both seams cross
//! its middle, as an 8-bit PNG.

#[path = "../tests/tiling_support/mod.rs"]
mod support;

use normalfit::tiling::{TilingOptions, check, shift_half};
use support::Rng;
use support::structured::{Camera, Look, Pattern, Rendered, Wrap, photo, texture};

/// One generated image and whether it must tile.
struct Item {
    group: &'static str,
    name: String,
    image: Rendered,
    tiles: bool,
}

/// The noises, photos and textures of one size, `per` of each kind.
fn items(w: usize, h: usize, per: usize, rng: &mut Rng) -> Vec<Item> {
    let mut out = Vec::new();
    for i in 0..per {
        let cells = [2, 3, 4, 6, 8][i % 5];
        let octaves = 1 + i % 3;
        let (cx, cy) = (cells, (cells * h / w).max(1));
        let seed = rng.next().to_bits();
        let t = support::quantize(&support::periodic_noise_xy(w, h, cx, cy, octaves, seed), 16);
        out.push(Item {
            group: "noise",
            name: format!("noise {cx}×{cy} {octaves}oct {w}×{h} #{i}"),
            image: Rendered { planes: vec![t], width: w, height: h },
            tiles: true,
        });
        let big = support::periodic_noise_xy(3 * w, 3 * h, 3 * cx, 3 * cy, octaves, seed + 1);
        let c = support::quantize(&support::crop(&big, 3 * w, w / 3 + 5 + i, h / 2 + 7 + i, w, h), 16);
        out.push(Item {
            group: "noise crop",
            name: format!("crop of noise {cx}×{cy} {octaves}oct {w}×{h} #{i}"),
            image: Rendered { planes: vec![c], width: w, height: h },
            tiles: false,
        });
        for pattern in Pattern::ALL {
            let rgb = i % 3 == 0;
            let angle = 3.0 + 40.0 * rng.next();
            let camera = Camera {
                angle: if rng.next() < 0.5 { angle } else { -angle },
                keystone: (0.3 * (rng.next() - 0.5), 0.3 * (rng.next() - 0.5)),
                zoom: 0.5 + 1.5 * rng.next(),
                light: if i % 2 == 0 { 0.0 } else { 0.3 * rng.next() },
                noise: 0.005 + 0.03 * rng.next(),
                rough: 0.25 * rng.next(),
            };
            let p = photo(pattern, w, h, camera, rng.next().to_bits(), rgb).quantized(8);
            let name = format!("{} photo {w}×{h} at {:.0}° #{i}", pattern.name(), camera.angle);
            out.push(Item { group: "structured photo", name, image: p, tiles: false });
            let wrap = match i % 5 {
                0 => Wrap::Rotate { p: 1, q: 0 },
                1 => Wrap::Rotate { p: 2, q: 1 },
                2 => Wrap::Shear { k: 1 + (i % 3) as i64 },
                3 => Wrap::Rotate { p: 3, q: -1 },
                _ => Wrap::Shear { k: -1 },
            };
            let (noise, rough) = (0.003 + 0.02 * rng.next(), 0.25 * rng.next());
            let t = texture(pattern, w, h, wrap, rng.next().to_bits(), Look { rgb, noise, rough });
            let t = t.quantized(if rgb { 8 } else { 16 });
            let name = format!("{} texture {w}×{h} {wrap:?} #{i}", pattern.name());
            out.push(Item { group: "structured texture", name, image: t, tiles: true });
        }
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).cloned();
    let per = arg("--per").and_then(|s| s.parse().ok()).unwrap_or(8);
    let dump = arg("--dump");
    let opts = TilingOptions::default();
    let default = [(64, 64), (96, 96), (128, 128), (256, 256), (512, 512), (512, 256), (256, 512)];
    // `--sizes 1024x1024,2048x1024`: other sizes than the threshold's.
    let sizes: Vec<(usize, usize)> = match arg("--sizes") {
        Some(list) => list
            .split(',')
            .map(|s| {
                let (w, h) = s.split_once('x').expect("--sizes WxH,WxH");
                (w.parse().expect("a width"), h.parse().expect("a height"))
            })
            .collect(),
        None => default.to_vec(),
    };
    let groups = ["noise", "structured texture", "noise crop", "structured photo"];
    let mut rng = Rng(2024);
    // Per group: (tileable max, non-tiling min) over the sizes, and a count.
    let mut total = vec![(0usize, 0usize, f64::NEG_INFINITY, f64::INFINITY); groups.len()];
    let mut wrong_names = Vec::new();
    println!("threshold {}; {per} images of each kind per size", opts.threshold);
    println!("| size | group | images | axes wrong | highest (tiles) | lowest (seam) |");
    println!("|---|---|---|---|---|---|");
    for (w, h) in sizes {
        let mut rows = vec![(0usize, 0usize, f64::NEG_INFINITY, f64::INFINITY); groups.len()];
        for item in items(w, h, per, &mut rng) {
            let r = check(&item.image.refs(), w, h, &opts).unwrap();
            let g = groups.iter().position(|&g| g == item.group).expect("known group");
            let row = &mut rows[g];
            row.0 += 1;
            for axis in [r.x, r.y] {
                if axis.seamless != item.tiles {
                    row.1 += 1;
                }
                if item.tiles {
                    row.2 = row.2.max(axis.score);
                } else {
                    row.3 = row.3.min(axis.score);
                }
            }
            if r.x.seamless != item.tiles || r.y.seamless != item.tiles {
                wrong_names.push(format!("{}: x {:.2}, y {:.2}", item.name, r.x.score, r.y.score));
                if let Some(dir) = &dump {
                    let luma = item.image.luma();
                    let bytes: Vec<u8> =
                        shift_half(&luma, w, h).unwrap().iter().map(|v| (v * 255.0).round() as u8).collect();
                    let file = format!("{dir}/{}.png", item.name.replace([' ', '/', '{', '}', ':', ','], "_"));
                    image::save_buffer(&file, &bytes, w as u32, h as u32, image::ExtendedColorType::L8)
                        .unwrap_or_else(|e| panic!("{file}: {e}"));
                }
            }
        }
        for (g, row) in rows.iter().enumerate() {
            let t = &mut total[g];
            (t.0, t.1, t.2, t.3) = (t.0 + row.0, t.1 + row.1, t.2.max(row.2), t.3.min(row.3));
            print_row(&format!("{w}×{h}"), groups[g], *row);
        }
    }
    for (g, row) in total.iter().enumerate() {
        print_row("all", groups[g], *row);
    }
    println!("\nwrongly judged images:");
    for n in &wrong_names {
        println!("  {n}");
    }
}

fn print_row(size: &str, group: &str, (images, wrong, high, low): (usize, usize, f64, f64)) {
    let show = |v: f64| if v.is_finite() { format!("{v:.2}") } else { String::new() };
    println!("| {size} | {group} | {images} | {wrong} | {} | {} |", show(high), show(low));
}
