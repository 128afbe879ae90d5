//! Helpers for the tiling tests and the `tiling_table` example: reading the
//! shared real textures (without `normalfit::io`, written elsewhere) and
//! making the generated cases.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// An image as the tiling check takes it: f32 planes in contract units.
pub struct Planes {
    /// One plane per channel, row-major.
    pub planes: Vec<Vec<f32>>,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl Planes {
    /// The planes as the slices `check` takes.
    pub fn refs(&self) -> Vec<&[f32]> {
        self.planes.iter().map(Vec::as_slice).collect()
    }

    /// A one-plane image.
    pub fn gray(plane: Vec<f32>, width: usize, height: usize) -> Self {
        assert_eq!(plane.len(), width * height);
        Planes { planes: vec![plane], width, height }
    }
}

/// `../shared/data` beside the crate, if it is there.
pub fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    dir.is_dir().then_some(dir)
}

/// Reads a PNG/JPEG with `image` or an EXR with `exr`, into contract units:
/// integers divided by 2^bits − 1, floats unchanged.
pub fn load(path: &Path) -> Planes {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        return load_exr(path);
    }
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (width, height) = (img.width() as usize, img.height() as usize);
    let channels = usize::from(img.color().channel_count());
    // `to_*32f` divides integers by their maximum and copies floats: the
    // contract's units, no gamma.
    let interleaved: Vec<f32> = match channels {
        1 => img.to_luma32f().into_raw(),
        2 => img.to_luma_alpha32f().into_raw(),
        3 => img.to_rgb32f().into_raw(),
        _ => img.to_rgba32f().into_raw(),
    };
    let c = channels.min(4);
    let planes = (0..c).map(|k| interleaved.iter().skip(k).step_by(c).copied().collect()).collect();
    Planes { planes, width, height }
}

fn load_exr(path: &Path) -> Planes {
    let img = exr::prelude::read_first_flat_layer_from_file(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let layer = img.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let channel = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .map(|c| c.sample_data.values_as_f32().collect::<Vec<f32>>())
    };
    let list = &layer.channel_data.list;
    let planes = if let Some(y) = channel("Y") {
        vec![y]
    } else if list.len() == 1 {
        vec![list[0].sample_data.values_as_f32().collect()]
    } else {
        ["R", "G", "B", "A"].iter().filter_map(|n| channel(n)).collect()
    };
    Planes { planes, width, height }
}

/// Deterministic pseudo-random numbers in [0, 1) (splitmix64), so the
/// generated cases are the same on every run without a dependency.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// One octave of smooth value noise on a lattice of `cells_x` × `cells_y`
/// cells, periodic with period `width` × `height` (the lattice wraps), each
/// cell `width / cells_x` texels wide. Smoothstep interpolation keeps the
/// slope continuous, so the only creases are ones a test puts there.
fn octave(width: usize, height: usize, cells_x: usize, cells_y: usize, rng: &mut Rng) -> Vec<f64> {
    let lattice: Vec<f64> = (0..cells_x * cells_y).map(|_| rng.next() * 2.0 - 1.0).collect();
    // A random shift of the lattice, so that the wrap does not always fall on
    // a lattice line, where smoothstep's slope is zero and every seam would
    // look unusually quiet.
    let (ox, oy) = (rng.next(), rng.next());
    let at = |i: usize, j: usize| lattice[(j % cells_y) * cells_x + i % cells_x];
    let smooth = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        let fy = y as f64 * cells_y as f64 / height as f64 + oy;
        let (j, ty) = (fy.floor() as usize, smooth(fy.fract()));
        for x in 0..width {
            let fx = x as f64 * cells_x as f64 / width as f64 + ox;
            let (i, tx) = (fx.floor() as usize, smooth(fx.fract()));
            let top = at(i, j) + tx * (at(i + 1, j) - at(i, j));
            let bottom = at(i, j + 1) + tx * (at(i + 1, j + 1) - at(i, j + 1));
            out.push(top + ty * (bottom - top));
        }
    }
    out
}

/// Value noise periodic with period `width` × `height`: `octaves` octaves,
/// the first with `cells` lattice cells across each axis, each next one
/// twice as fine at half the amplitude. Mapped into [0, 1].
pub fn periodic_noise(width: usize, height: usize, cells: usize, octaves: usize, seed: u64) -> Vec<f32> {
    periodic_noise_xy(width, height, cells, cells, octaves, seed)
}

/// Like [`periodic_noise`] with separate cell counts per axis.
pub fn periodic_noise_xy(width: usize, height: usize, cx: usize, cy: usize, octaves: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let mut sum = vec![0.0f64; width * height];
    let mut amp = 1.0;
    for o in 0..octaves {
        let layer = octave(width, height, cx << o, cy << o, &mut rng);
        for (s, v) in sum.iter_mut().zip(layer) {
            *s += amp * v;
        }
        amp *= 0.5;
    }
    normalize(&sum)
}

/// Maps values linearly onto [0, 1].
pub fn normalize(v: &[f64]) -> Vec<f32> {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = if hi > lo { hi - lo } else { 1.0 };
    v.iter().map(|&x| ((x - lo) / span) as f32).collect()
}

/// A `w` × `h` window at (x0, y0) of a `big_w`-wide image.
pub fn crop(src: &[f32], big_w: usize, x0: usize, y0: usize, w: usize, h: usize) -> Vec<f32> {
    (y0..y0 + h).flat_map(|y| src[y * big_w + x0..][..w].iter().copied()).collect()
}

/// Rounds to `bits`-bit integers and back to contract units, as a file would.
pub fn quantize(v: &[f32], bits: u32) -> Vec<f32> {
    let max = ((1u64 << bits) - 1) as f32;
    v.iter().map(|&x| (x.clamp(0.0, 1.0) * max).round() / max).collect()
}

/// The encoded normal map (c = (n + 1)/2, three planes) of a height map,
/// fitted with `normalfit::normals`: wrap borders for a map meant to tile,
/// clamp borders for one that is not (wrapping a crop's fit would carry its
/// seam into a smooth ridge across the wrap instead of a jump).
pub fn normal_map_planes(heights: &[f32], w: usize, h: usize, scale: f64, wrap: bool) -> Planes {
    let border = if wrap { normalfit::Border::Wrap } else { normalfit::Border::Clamp };
    let opts = normalfit::Options::default()
        .with_strength(normalfit::Strength::Scale(scale))
        .with_borders(normalfit::Borders::both(border));
    let n = normalfit::normals(heights, w, h, &opts).expect("fit");
    let planes = (0..3).map(|c| n.iter().map(|t| (t[c] + 1.0) * 0.5).collect()).collect();
    Planes { planes, width: w, height: h }
}

/// A profile along x, h(t) for t = x / W in [0, 1).
type Profile = fn(f64) -> f64;

/// A test image with the verdict it must get.
pub struct Case {
    /// Short description, for the table.
    pub name: String,
    /// The image.
    pub image: Planes,
    /// Must it tile along x, along y?
    pub expect: (bool, bool),
    /// The kind `Auto` must find.
    pub kind: normalfit::normal_map::ImageKind,
}

/// The shared real textures with their verdicts, when `../shared/data` is there.
pub fn real_cases() -> Option<Vec<Case>> {
    use normalfit::normal_map::ImageKind::{Height, Normal};
    let dir = data_dir()?;
    let files = [
        ("tileable/ambientcg_Bricks061/Bricks061_1K-JPG_Displacement.jpg", true, Height),
        ("tileable/ambientcg_Bricks061/Bricks061_1K-JPG_NormalGL.jpg", true, Normal),
        ("tileable/ambientcg_Bricks061/Bricks061_1K-JPG_NormalDX.jpg", true, Normal),
        ("tileable/polyhaven_denim_fabric/denim_fabric_disp_1k.png", true, Height),
        ("tileable/polyhaven_denim_fabric/denim_fabric_nor_gl_1k.png", true, Normal),
        ("tileable/materialx_adsk_bricks_02/bricks_02_height_2k_raw.exr", true, Height),
        ("tileable/materialx_adsk_bricks_02/bricks_02_normal_2k_raw.exr", true, Normal),
        ("tileable/materialx_adsk_bricks_02/bricks_02_normal_2k_raw.png", true, Normal),
        ("non_tiling/skimage_camera.png", false, Height),
        ("non_tiling/skimage_coffee.png", false, Height),
    ];
    Some(
        files
            .iter()
            .map(|&(f, tiles, kind)| Case {
                name: f.rsplit('/').next().unwrap_or(f).to_string(),
                image: load(&dir.join(f)),
                expect: (tiles, tiles),
                kind,
            })
            .collect(),
    )
}

fn gray_case(name: String, v: Vec<f32>, n: usize, expect: (bool, bool)) -> Case {
    Case { name, image: Planes::gray(v, n, n), expect, kind: normalfit::normal_map::ImageKind::Height }
}

/// The generated cases, at side `n`, quantised to 16 bits as a PNG would
/// hold them (the normal maps stay float).
pub fn generated_cases(n: usize) -> Vec<Case> {
    use normalfit::normal_map::ImageKind::Normal;
    let mut cases = Vec::new();
    // Noise at several frequencies: (cells of the first octave, octaves).
    // The finest octave keeps cells of at least 8 texels: white noise
    // tiles whatever is done to it, so a crop of it is no test.
    for (cells, octaves) in [(2, 1), (3, 3), (4, 2), (n / 16, 1)] {
        let seed = (n * 31 + cells * 7 + octaves) as u64;
        let t = periodic_noise(n, n, cells, octaves, seed);
        cases.push(gray_case(format!("noise {cells}×{octaves}oct n{n}"), quantize(&t, 16), n, (true, true)));
        // A window of a periodic noise three times as large, off its period.
        let big = periodic_noise(3 * n, 3 * n, 3 * cells, octaves, seed + 1);
        let c = crop(&big, 3 * n, n / 3 + 5, n / 2 + 7, n, n);
        cases.push(gray_case(format!("crop of noise {cells}×{octaves}oct n{n}"), quantize(&c, 16), n, (false, false)));
    }
    // Periodic along x only: a crop in y of noise periodic in x.
    let tall = periodic_noise_xy(n, 3 * n, 4, 12, 2, n as u64);
    let c = crop(&tall, n, 0, n / 2 + 3, n, n);
    cases.push(gray_case(format!("noise periodic in x only n{n}"), quantize(&c, 16), n, (true, false)));

    // Value-continuous, slope-creased wraps: a smooth noise plus a profile
    // along x whose ends meet in value but not in slope.
    let base = periodic_noise(n, n, 2, 2, 77 + n as u64);
    let nf = n as f64;
    let profiles: [(&str, Profile); 3] = [
        ("half sine", |t| (std::f64::consts::PI * t).sin()),
        ("parabola", |t| 4.0 * t * (1.0 - t)),
        ("triangle |x − W/2|", |t| 1.0 - (2.0 * t - 1.0).abs()),
    ];
    for (label, f) in &profiles {
        let v: Vec<f64> = (0..n * n).map(|k| 0.5 * f((k % n) as f64 / nf) + 0.5 * f64::from(base[k])).collect();
        cases.push(gray_case(format!("{label} crease + noise n{n}"), quantize(&normalize(&v), 16), n, (false, true)));
    }

    // Normal maps fitted from a tileable height and from a crop.
    let t = periodic_noise(n, n, 4, 3, 5 + n as u64);
    let mut m = normal_map_planes(&t, n, n, 8.0, true);
    cases.push(Case { name: format!("normal map of noise n{n}"), image: m, expect: (true, true), kind: Normal });
    let big = periodic_noise(3 * n, 3 * n, 12, 3, 6 + n as u64);
    let c = crop(&big, 3 * n, n / 3 + 5, n / 2 + 7, n, n);
    m = normal_map_planes(&c, n, n, 8.0, false);
    cases.push(Case { name: format!("normal map of crop n{n}"), image: m, expect: (false, false), kind: Normal });
    cases
}

/// The contract's public cases (SPEC section 4 conformance): a 16-bit sine
/// that tiles, a ramp along x that tiles only along y; and a constant.
pub fn spec_cases() -> Vec<Case> {
    let n = 96;
    let nf = n as f64;
    let sine: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64, (k / n) as f64);
            let v = (32767.5 + 30000.0 * (2.0 * std::f64::consts::PI * (2.0 * x / nf + y / nf)).sin()).trunc();
            (v / 65535.0) as f32
        })
        .collect();
    let ramp: Vec<f32> =
        (0..n * n).map(|k| ((65535.0 * (k % n) as f64 / (nf - 1.0)).trunc() / 65535.0) as f32).collect();
    vec![
        gray_case("SPEC sine 96² 16-bit".into(), sine, n, (true, true)),
        gray_case("SPEC ramp along x 96² 16-bit".into(), ramp, n, (false, true)),
        gray_case("constant 0.4 32²".into(), vec![0.4; 32 * 32], 32, (true, true)),
    ]
}

pub mod structured;

/// Structured images (see [`structured`]): photos of brick walls, planks,
/// tiles and cables at angles, which must fail on both axes, and exactly
/// periodic textures of the same, which must tile. 8-bit photos (gray and
/// RGB, as cameras give), 16-bit gray or 8-bit RGB textures.
pub fn structured_cases(n: usize) -> Vec<Case> {
    use normalfit::normal_map::ImageKind::Height;
    use structured::{Camera, Look, Pattern, Wrap, photo, texture};
    let mut cases = Vec::new();
    let case = |name: String, r: structured::Rendered, tiles: bool| Case {
        name,
        image: Planes { planes: r.planes, width: r.width, height: r.height },
        expect: (tiles, tiles),
        kind: Height,
    };
    // Photos: an even light (no falloff to give the seam away), a rough
    // surface, little sensor noise: the seam is only the structure that
    // does not continue.
    let photos = [
        (Pattern::Bricks, 12.0, false, 0.15),
        (Pattern::Bricks, -27.0, true, 0.2),
        (Pattern::Planks, 20.0, false, 0.1),
        (Pattern::Tiles, 33.0, false, 0.1),
        (Pattern::Cables, -24.0, true, 0.1),
    ];
    for (i, &(pattern, angle, rgb, rough)) in photos.iter().enumerate() {
        let camera = Camera { light: 0.0, noise: 0.01, rough, ..Camera::at(angle) };
        let p = photo(pattern, n, n, camera, 40 + i as u64, rgb).quantized(8);
        let colour = if rgb { "RGB" } else { "gray" };
        cases.push(case(format!("{} photo at {angle}°, {colour} n{n}", pattern.name()), p, false));
    }
    let textures = [
        (Pattern::Bricks, Wrap::Rotate { p: 1, q: 0 }, false),
        (Pattern::Bricks, Wrap::Rotate { p: 2, q: 1 }, true),
        (Pattern::Planks, Wrap::Shear { k: 1 }, false),
        (Pattern::Tiles, Wrap::Rotate { p: 3, q: -1 }, false),
        (Pattern::Cables, Wrap::Shear { k: -2 }, false),
    ];
    for (i, &(pattern, wrap, rgb)) in textures.iter().enumerate() {
        let t = texture(pattern, n, n, wrap, 60 + i as u64, Look { rgb, noise: 0.01, rough: 0.15 });
        let t = t.quantized(if rgb { 8 } else { 16 });
        let how = match wrap {
            Wrap::Rotate { p: 1, q: 0 } => "square".to_string(),
            Wrap::Rotate { p, q } => format!("rotated atan({q}/{p})"),
            Wrap::Shear { k } => format!("lines at atan({k})"),
        };
        cases.push(case(format!("periodic {} {how} n{n}", pattern.name()), t, true));
    }
    // Lines at atan(k·H/W) in a non-square image: periodic on both axes.
    let (w, h) = (n, n / 2);
    let look = Look { rgb: false, noise: 0.01, rough: 0.15 };
    let t = texture(Pattern::Planks, w, h, Wrap::Shear { k: 1 }, 70, look).quantized(16);
    cases.push(Case {
        name: format!("periodic planks, lines at atan(H/W), {w}×{h}"),
        image: Planes { planes: t.planes, width: w, height: h },
        expect: (true, true),
        kind: Height,
    });
    cases
}

/// Photos that the seam measure at level 0 alone (texel by texel, as it
/// was before the runs along the seam) passed on both axes or on one:
/// 512² planks at ±38° and 25°, zoomed in 1.5×, on rough wood with little
/// sensor noise and an even light. The broken plank gaps are the only
/// seam; each must fail on both axes.
pub fn hard_photo_cases() -> Vec<Case> {
    use structured::{Camera, Pattern, photo};
    let n = 512;
    [(-38.0, 300), (38.0, 301), (25.0, 300)]
        .iter()
        .map(|&(angle, seed)| {
            let camera = Camera { light: 0.0, noise: 0.01, rough: 0.25, zoom: 1.5, ..Camera::at(angle) };
            let p = photo(Pattern::Planks, n, n, camera, seed, false).quantized(8);
            Case {
                name: format!("rough planks photo at {angle}°, zoom 1.5, n{n}"),
                image: Planes { planes: p.planes, width: n, height: n },
                expect: (false, false),
                kind: normalfit::normal_map::ImageKind::Height,
            }
        })
        .collect()
}
