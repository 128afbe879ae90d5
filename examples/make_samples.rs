//! Generates the sample height maps in `samples/`, with their normal maps,
//! so the README and the tests have pictures the project owns outright; and
//! the same maps at half size in `docs/gallery/`, from which the README's
//! gallery is made by `normalfit convert` and `normalfit shade` (the
//! commands are in the README).
//!
//! ```text
//! cargo run --release --example make_samples
//! ```
//!
//! Everything is deterministic: the noise is hand-written lattice noise
//! driven by an integer hash with fixed seeds, so the files only change when
//! this program does. Two of the maps tile (`bricks`, `rock`): every lattice
//! they use has a whole number of cells across the image and wraps its cell
//! index, so the field at x = W equals the field at x = 0. `terrain` is cut
//! from an unbounded field on purpose, so the tiling check has a map that
//! fails.

use std::f64::consts::TAU;
use std::path::Path;

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use normalfit::{Border, Borders, FitRequest, Options, Strength};

/// Side of every sample, in texels.
const SIZE: usize = 512;

/// Side of the gallery's height maps: small pictures for the README.
const GALLERY_SIZE: usize = SIZE / 2;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let gallery = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs").join("gallery");
    std::fs::create_dir_all(&dir)?;
    std::fs::create_dir_all(&gallery)?;
    let wrap = Options::default();
    let samples = [
        Sample {
            name: "bricks",
            make: || render(bricks),
            opts: wrap.clone().with_strength(Strength::Scale(BRICKS_SCALE)),
        },
        Sample { name: "rock", make: || render(rock), opts: wrap.with_strength(Strength::Scale(ROCK_SCALE)) },
        // Not tileable, so wrapping would put a false cliff at the edges;
        // N = 5 smooths the texel-scale erosion noise a little.
        Sample {
            name: "terrain",
            make: || erode(render(terrain)),
            opts: Options::default()
                .with_patch(5)
                .with_borders(Borders::both(Border::Clamp))
                .with_strength(Strength::Scale(TERRAIN_SCALE)),
        },
    ];
    for Sample { name, make, opts } in samples {
        let heights = quantize(&make());
        // The encoder takes 16-bit samples in native byte order.
        let bytes: Vec<u8> = heights.iter().flat_map(|v| v.to_ne_bytes()).collect();
        write_png(&dir.join(format!("{name}.png")), &bytes, SIZE, ExtendedColorType::L16)?;

        // The normals are made from the 16-bit values just written, so they
        // are exactly what `normalfit` gives for the file.
        let h: Vec<f32> = heights.iter().map(|&v| f32::from(v) / 65535.0).collect();
        let mut rgb = vec![[0u8; 3]; h.len()];
        FitRequest::new(&opts).normals_into(&h, SIZE, SIZE, &mut rgb)?;
        write_png(&dir.join(format!("{name}_normal.png")), rgb.as_flattened(), SIZE, ExtendedColorType::Rgb8)?;

        write_png(
            &gallery.join(format!("{name}.png")),
            &half_size_8_bit(&heights),
            GALLERY_SIZE,
            ExtendedColorType::L8,
        )?;
        println!("wrote samples/{name}.png, {name}_normal.png and docs/gallery/{name}.png");
    }
    Ok(())
}

/// One sample: its file stem, its height field, the options its normal
/// map is made with.
struct Sample {
    name: &'static str,
    make: fn() -> Vec<f64>,
    opts: Options,
}

/// Heights of the samples span [0, 1]; these gains (texel widths per unit
/// of height) give each a relief that reads well at 512². The contract's
/// default of 1 suits maps whose detail is a few texels deep at most.
const BRICKS_SCALE: f64 = 8.0;
const ROCK_SCALE: f64 = 16.0;
const TERRAIN_SCALE: f64 = 40.0;

/// Samples `field(u, v)` at texel centres, u and v in [0, 1) across the image.
fn render(field: fn(f64, f64) -> f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(SIZE * SIZE);
    for y in 0..SIZE {
        for x in 0..SIZE {
            out.push(field((x as f64 + 0.5) / SIZE as f64, (y as f64 + 0.5) / SIZE as f64));
        }
    }
    out
}

/// Stretches the field onto the full 16-bit range.
fn quantize(field: &[f64]) -> Vec<u16> {
    let (lo, hi) = field.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    field.iter().map(|&v| ((v - lo) / (hi - lo) * 65535.0).round() as u16).collect()
}

/// The sample at half its size and in 8 bits, each texel the mean of a 2×2
/// block, rounded (ties up): a small file for the README, with the same
/// relief. 8 bits are enough for pictures: at the gallery's gains (the
/// samples' halved) rounding to 8 bits tilts a fitted normal by at most
/// 1.3° (terrain, N = 5; under 1° for the others), and the lit views of the
/// 8- and 16-bit maps look the same.
fn half_size_8_bit(heights: &[u16]) -> Vec<u8> {
    let at = |x: usize, y: usize| u32::from(heights[y * SIZE + x]);
    // Four 16-bit values sum to at most 4 · 65535; 8 bits are 16 bits / 257.
    let (sum_per_level, half) = (4 * 257, 2 * 257);
    let mut out = Vec::with_capacity(GALLERY_SIZE * GALLERY_SIZE);
    for y in 0..GALLERY_SIZE {
        for x in 0..GALLERY_SIZE {
            let sum = at(2 * x, 2 * y) + at(2 * x + 1, 2 * y) + at(2 * x, 2 * y + 1) + at(2 * x + 1, 2 * y + 1);
            out.push(u8::try_from((sum + half) / sum_per_level).expect("the mean of four u16 over 257 is a u8"));
        }
    }
    out
}

/// A square PNG of `side` texels. Best compression: the files are
/// committed, so size matters more than the second it costs.
fn write_png(
    path: &Path,
    bytes: &[u8],
    side: usize,
    color: ExtendedColorType,
) -> Result<(), Box<dyn std::error::Error>> {
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let side = side as u32;
    PngEncoder::new_with_quality(file, CompressionType::Best, FilterType::Adaptive)
        .write_image(bytes, side, side, color)?;
    Ok(())
}

// ---------------------------------------------------------------- noise --

/// A 32-bit hash of a lattice point and a seed (a murmur3-style finaliser
/// over a mix of the inputs): cheap, and good enough that neighbouring
/// cells look unrelated.
fn hash(x: i64, y: i64, seed: u32) -> u32 {
    let mut h =
        (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841) ^ seed.wrapping_mul(0xcb1a_b31f);
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

/// The hash as a number in [0, 1).
fn hash01(x: i64, y: i64, seed: u32) -> f64 {
    f64::from(hash(x, y, seed)) / 4_294_967_296.0
}

/// The lattice: `Some(p)` wraps cell indices modulo p on both axes, which
/// makes the noise periodic with period p cells; `None` never repeats.
type Period = Option<i64>;

fn cell(i: i64, period: Period) -> i64 {
    period.map_or(i, |p| i.rem_euclid(p))
}

/// Quintic fade: C2 continuous, so the normals (first derivatives) of the
/// noise have no creases at cell borders.
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn fade_d(t: f64) -> f64 {
    30.0 * t * t * (t * (t - 2.0) + 1.0)
}

/// Gradient (Perlin) noise at (x, y) in lattice units, about [−0.7, 0.7].
fn gradient(x: f64, y: f64, period: Period, seed: u32) -> f64 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let corner = |dx: i64, dy: i64| {
        let (i, j) = (cell(x0 as i64 + dx, period), cell(y0 as i64 + dy, period));
        let a = hash01(i, j, seed) * TAU;
        a.cos() * (fx - dx as f64) + a.sin() * (fy - dy as f64)
    };
    let (u, v) = (fade(fx), fade(fy));
    let top = corner(0, 0) + u * (corner(1, 0) - corner(0, 0));
    let bottom = corner(0, 1) + u * (corner(1, 1) - corner(0, 1));
    top + v * (bottom - top)
}

/// Value noise in [−1, 1] with its derivatives (d/dx, d/dy), for the
/// erosion-like fBm of the terrain.
fn value_d(x: f64, y: f64, period: Period, seed: u32) -> (f64, f64, f64) {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |dx: i64, dy: i64| hash01(cell(x0 as i64 + dx, period), cell(y0 as i64 + dy, period), seed) * 2.0 - 1.0;
    let (a, b, c, d) = (at(0, 0), at(1, 0), at(0, 1), at(1, 1));
    let (u, v) = (fade(fx), fade(fy));
    let k = a - b - c + d;
    let value = a + (b - a) * u + (c - a) * v + k * u * v;
    (value, fade_d(fx) * ((b - a) + k * v), fade_d(fy) * ((c - a) + k * u))
}

/// Fractal sum of gradient noise over image coordinates u, v ∈ [0, 1):
/// octave k has `cells · 2^k` cells across the image, wrapped, so the sum
/// tiles with the image.
fn fbm_tiled(u: f64, v: f64, cells: i64, octaves: u32, gain: f64, seed: u32) -> f64 {
    let (mut sum, mut amp, mut p) = (0.0, 1.0, cells);
    for k in 0..octaves {
        sum += amp * gradient(u * p as f64, v * p as f64, Some(p), seed.wrapping_add(k * 1013));
        amp *= gain;
        p *= 2;
    }
    sum
}

/// Distances to the nearest and second-nearest feature point of a wrapped
/// Worley (cellular) lattice with `cells` cells across the image, in cell
/// units, and the nearest point's cell id (for per-plate values).
fn worley_tiled(u: f64, v: f64, cells: i64, seed: u32) -> (f64, f64, (i64, i64)) {
    let (x, y) = (u * cells as f64, v * cells as f64);
    let (cx, cy) = (x.floor() as i64, y.floor() as i64);
    let (mut f1, mut f2, mut id) = (f64::MAX, f64::MAX, (0, 0));
    for dy in -1..=1 {
        for dx in -1..=1 {
            let (i, j) = (cx + dx, cy + dy);
            let (wi, wj) = (i.rem_euclid(cells), j.rem_euclid(cells));
            let px = i as f64 + 0.1 + 0.8 * hash01(wi, wj, seed);
            let py = j as f64 + 0.1 + 0.8 * hash01(wi, wj, seed ^ 0x9e37);
            let d = ((px - x).powi(2) + (py - y).powi(2)).sqrt();
            if d < f1 {
                (f2, f1, id) = (f1, d, (wi, wj));
            } else if d < f2 {
                f2 = d;
            }
        }
    }
    (f1, f2, id)
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

// --------------------------------------------------------------- fields --

/// Running-bond bricks: 5 bricks a course, 14 courses (bricks about 102 ×
/// 37 texels), every other course shifted half a brick. Whole numbers of
/// bricks and courses across the image make the pattern tile.
fn bricks(u: f64, v: f64) -> f64 {
    const COLS: f64 = 5.0;
    const ROWS: f64 = 14.0;
    let texel = 1.0 / SIZE as f64;
    // Wobble the coordinates a texel or two so edges are not ruler-straight.
    let wu = u + 1.6 * texel * fbm_tiled(u, v, 16, 3, 0.5, 11);
    let wv = v + 1.6 * texel * fbm_tiled(u, v, 16, 3, 0.5, 12);

    let row = (wv * ROWS).floor();
    let shift = if (row as i64).rem_euclid(2) == 1 { 0.5 } else { 0.0 };
    let bx = wu * COLS + shift;
    let col = bx.floor();
    let id = ((col as i64).rem_euclid(COLS as i64), (row as i64).rem_euclid(ROWS as i64));
    // Position inside the brick, in texels from its left/top edge.
    let (bw, bh) = (SIZE as f64 / COLS, SIZE as f64 / ROWS);
    let (lx, ly) = ((bx - col) * bw, (wv * ROWS - row) * bh);
    // Distance inside a rounded rectangle, so corners bevel round.
    let (ex, ey) = (lx.min(bw - lx), ly.min(bh - ly));
    let r = 4.0;
    let edge = if ex < r && ey < r { r - ((r - ex).powi(2) + (r - ey).powi(2)).sqrt() } else { ex.min(ey) };

    let mortar_half = 2.5;
    // Chipped arrises: noise eats into the bevel, more in some places.
    let chips = 4.0 * fbm_tiled(u, v, 24, 4, 0.55, 21).max(-0.1) + 0.4;
    let inside = edge - mortar_half - chips.max(0.0);
    let bevel = 4.0;
    let t = (inside / bevel).clamp(0.0, 1.0);
    let profile = 1.0 - (1.0 - t).powi(2);

    // Per-brick: a height offset and a slight tilt, as laid by hand.
    let (i, j) = id;
    let lift = 0.14 * (hash01(i, j, 31) - 0.5);
    let tilt_x = 0.12 * (hash01(i, j, 32) - 0.5) * (lx / bw - 0.5);
    let tilt_y = 0.10 * (hash01(i, j, 33) - 0.5) * (ly / bh - 0.5);
    // Fired-clay surface: low-frequency waviness plus fine grain and pits.
    let surface = 0.06 * fbm_tiled(u, v, 8, 3, 0.5, 41) + 0.035 * fbm_tiled(u, v, 64, 3, 0.65, 42);
    let pits = -0.04 * smoothstep(0.35, 0.5, fbm_tiled(u, v, 96, 2, 0.5, 43));
    let top = 0.75 + lift + tilt_x + tilt_y + surface + pits;

    // Mortar: recessed, sandy.
    let mortar = 0.12 + 0.03 * fbm_tiled(u, v, 96, 2, 0.5, 51) + 0.03 * fbm_tiled(u, v, 12, 2, 0.5, 52);
    mortar + (top - mortar).max(0.0) * profile
}

/// Rock: fractured plates (wrapped Worley cells at different heights, split
/// by cracks) under ridged fractal noise.
fn rock(u: f64, v: f64) -> f64 {
    // Warp the plate pattern so the fractures are not straight Voronoi edges.
    let wu = u + 0.045 * fbm_tiled(u, v, 4, 5, 0.5, 61);
    let wv = v + 0.045 * fbm_tiled(u, v, 4, 5, 0.5, 62);
    let (f1, f2, (i, j)) = worley_tiled(wu, wv, 5, 63);
    let plate = 0.25 * hash01(i, j, 64);
    // Cracks along the cell borders (where f2 − f1 is small), fine ones
    // within the plates from a second, smaller lattice.
    let crack = smoothstep(0.0, 0.08, f2 - f1);
    let (g1, g2, _) = worley_tiled(wu + 0.01 * fbm_tiled(u, v, 16, 2, 0.5, 66), wv, 9, 65);
    let fine = smoothstep(0.0, 0.03, g2 - g1);

    // Ridged fBm: 1 − |n| makes sharp crests; squared, they sharpen more.
    let (mut ridged, mut amp, mut p) = (0.0, 0.5, 3);
    for k in 0..6 {
        let n = gradient(wu * p as f64, wv * p as f64, Some(p), 70 + k);
        ridged += amp * (1.0 - n.abs() * 1.6).max(0.0).powi(3);
        amp *= 0.65;
        p *= 2;
    }
    let base = 0.5 * fbm_tiled(u, v, 2, 3, 0.5, 80);
    let grain = 0.05 * fbm_tiled(u, v, 64, 3, 0.6, 81);
    base + plate + 0.6 * ridged + grain - 0.22 * (1.0 - crack) - 0.04 * (1.0 - fine)
}

/// Eroded-looking terrain: fBm whose octaves are damped where the slope is
/// steep (so valleys stay smooth and ridges keep detail, as erosion leaves
/// them), sampled through a domain warp. The window is cut from an
/// unbounded field, so it does not tile.
fn terrain(u: f64, v: f64) -> f64 {
    // An off-centre window of the plane, so nothing lines up with a lattice.
    let (x, y) = (u * 3.0 + 17.31, v * 3.0 - 5.77);
    let warp = |x: f64, y: f64, seed: u32| {
        let (mut s, mut a, mut f) = (0.0, 1.0, 1.0);
        for k in 0..4 {
            s += a * gradient(x * f, y * f, None, seed + k);
            a *= 0.5;
            f *= 2.0;
        }
        s
    };
    let (qx, qy) = (warp(x, y, 90), warp(x + 5.2, y + 1.3, 95));
    let (mut px, mut py) = (x + 0.6 * qx, y + 0.6 * qy);

    let (mut sum, mut amp, mut dx, mut dy) = (0.0, 0.5, 0.0, 0.0);
    for k in 0..9 {
        let (n, nx, ny) = value_d(px, py, None, 100 + k);
        dx += nx;
        dy += ny;
        sum += amp * n / (1.0 + dx * dx + dy * dy);
        amp *= 0.5;
        // Rotate between octaves so lattice axes do not stack up.
        (px, py) = (2.0 * (0.8 * px - 0.6 * py), 2.0 * (0.6 * px + 0.8 * py));
    }
    sum
}

/// Hydraulic erosion by droplets (after Hans Theobald Beyer's method):
/// each droplet runs downhill with some inertia, picks up sediment while it
/// speeds up and drops it where it slows or climbs. It carves the branching
/// gullies and smooth fans that noise alone does not give. Droplets start at
/// hashed positions, so the result is deterministic.
fn erode(mut map: Vec<f64>) -> Vec<f64> {
    const DROPLETS: u32 = 140_000;
    const LIFETIME: usize = 48;
    const INERTIA: f64 = 0.08;
    const CAPACITY: f64 = 6.0;
    const MIN_CAPACITY: f64 = 0.0005;
    const DEPOSIT: f64 = 0.25;
    const ERODE: f64 = 0.35;
    const EVAPORATE: f64 = 0.02;
    const GRAVITY: f64 = 6.0;
    const RADIUS: i64 = 2;
    let n = SIZE as i64;
    // Heights in texel units, with the relief the normal map will show, so
    // droplets feel the slopes a viewer sees.
    let (lo, hi) = map.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    for h in &mut map {
        *h = (*h - lo) / (hi - lo) * TERRAIN_SCALE;
    }
    let brush: Vec<(i64, i64, f64)> = {
        let mut b = Vec::new();
        for dy in -RADIUS..=RADIUS {
            for dx in -RADIUS..=RADIUS {
                let w = RADIUS as f64 + 0.5 - ((dx * dx + dy * dy) as f64).sqrt();
                if w > 0.0 {
                    b.push((dx, dy, w));
                }
            }
        }
        let total: f64 = b.iter().map(|t| t.2).sum();
        b.into_iter().map(|(x, y, w)| (x, y, w / total)).collect()
    };
    let idx = |x: i64, y: i64| (y * n + x) as usize;
    // Bilinear height and gradient at a point inside [0, n − 1)².
    let sample = |map: &[f64], x: f64, y: f64| {
        let (cx, cy) = (x.floor() as i64, y.floor() as i64);
        let (fx, fy) = (x - cx as f64, y - cy as f64);
        let (a, b) = (map[idx(cx, cy)], map[idx(cx + 1, cy)]);
        let (c, d) = (map[idx(cx, cy + 1)], map[idx(cx + 1, cy + 1)]);
        let gx = (b - a) * (1.0 - fy) + (d - c) * fy;
        let gy = (c - a) * (1.0 - fx) + (d - b) * fx;
        let h = a * (1.0 - fx) * (1.0 - fy) + b * fx * (1.0 - fy) + c * (1.0 - fx) * fy + d * fx * fy;
        (h, gx, gy)
    };
    let limit = (n - 1) as f64;
    for drop in 0..DROPLETS {
        let mut x = hash01(i64::from(drop), 0, 201) * limit;
        let mut y = hash01(i64::from(drop), 1, 201) * limit;
        let (mut dx, mut dy, mut speed, mut water, mut sediment) = (0.0, 0.0, 1.0, 1.0, 0.0f64);
        for _ in 0..LIFETIME {
            let (cx, cy) = (x.floor() as i64, y.floor() as i64);
            let (h, gx, gy) = sample(&map, x, y);
            dx = dx * INERTIA - gx * (1.0 - INERTIA);
            dy = dy * INERTIA - gy * (1.0 - INERTIA);
            let len = (dx * dx + dy * dy).sqrt();
            if len < 1e-12 {
                break;
            }
            (dx, dy) = (dx / len, dy / len);
            x += dx;
            y += dy;
            if !(0.0..limit).contains(&x) || !(0.0..limit).contains(&y) {
                break;
            }
            let dh = sample(&map, x, y).0 - h;
            let capacity = (-dh * speed * water * CAPACITY).max(MIN_CAPACITY);
            if sediment > capacity || dh > 0.0 {
                // Fill the pit it climbs out of, or shed what it cannot carry.
                let amount = if dh > 0.0 { dh.min(sediment) } else { (sediment - capacity) * DEPOSIT };
                sediment -= amount;
                // Spread like the erosion, or thin levees build up.
                let mut kept = 0.0;
                for &(bx, by, w) in &brush {
                    let (px, py) = (cx + bx, cy + by);
                    if (0..n).contains(&px) && (0..n).contains(&py) {
                        map[idx(px, py)] += amount * w;
                        kept += w;
                    }
                }
                sediment += amount * (1.0 - kept);
            } else {
                // Never dig deeper than the step down, or it digs pits.
                let amount = ((capacity - sediment) * ERODE).min(-dh);
                for &(bx, by, w) in &brush {
                    let (px, py) = (cx + bx, cy + by);
                    if (0..n).contains(&px) && (0..n).contains(&py) {
                        let k = idx(px, py);
                        let take = (amount * w).min(map[k].max(0.0));
                        map[k] -= take;
                        sediment += take;
                    }
                }
            }
            speed = (speed * speed - dh * GRAVITY).max(0.0).sqrt();
            water *= 1.0 - EVAPORATE;
        }
    }
    // One 3×3 box blur: single-texel spikes where droplets stopped would
    // otherwise read as noise in the normal map.
    let mut out = map.clone();
    for y in 0..n {
        for x in 0..n {
            let mut sum = 0.0;
            for (dx, dy) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dx, dy))) {
                sum += map[idx((x + dx).clamp(0, n - 1), (y + dy).clamp(0, n - 1))];
            }
            out[idx(x, y)] = sum / 9.0;
        }
    }
    out
}
