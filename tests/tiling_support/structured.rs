//! Structured images for the tiling check: brick walls, planks, tiles and
//! cables, rendered two ways.
//!
//! * **Photos** ([`photo`]): the scene seen at an angle, with perspective,
//!   uneven lighting and sensor noise, through a window placed anywhere on
//!   an unbounded scene. The straight lines (mortar, plank gaps, grout,
//!   cables) hit the borders at positions that do not match the opposite
//!   border, so the image does not tile, though each texel's jump at the
//!   wrap may be no larger than the jumps at the scene's own edges.
//! * **Textures** ([`texture`]): the same scenes made exactly periodic. The
//!   scene lives on a torus of side `T` (a whole number of bricks, planks,
//!   tiles across it; every hash and noise lattice wraps its index), and the
//!   image maps onto it by an integer matrix: texel (x, y) is scene point
//!   `T·(p·x/W − q·y/H, q·x/W + p·y/H)` (a rotation by atan(q/p), seen
//!   squarely when W = H) or `T·(x/W, k·x/W + y/H)` (a shear: lines at
//!   angle atan(k·H/W)). Moving x by W moves the scene point by whole
//!   periods, so the image tiles on both axes. Sensor noise, drawn per
//!   texel, is no seam.
//!
//! Everything is deterministic (hashes of integer coordinates and a seed).
//! Each texel averages 2×2 samples, so lines are antialiased as a camera
//! or a renderer would draw them.

use std::f64::consts::TAU;

use super::Rng;

/// What a scene shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pattern {
    /// Running-bond brick wall: bricks 64 × 32 scene units, light mortar
    /// 5 units wide, beveled and lit from above.
    Bricks,
    /// Floor planks 24 units wide and 128 long, staggered, with dark gaps
    /// 2.5 units wide and wood grain along them.
    Planks,
    /// Square tiles of 32 units with dark grout 3 units wide.
    Tiles,
    /// Dark sagging cables 5 units thick, 32 units apart, on a mottled wall.
    Cables,
}

impl Pattern {
    pub const ALL: [Pattern; 4] = [Pattern::Bricks, Pattern::Planks, Pattern::Tiles, Pattern::Cables];

    pub fn name(self) -> &'static str {
        match self {
            Pattern::Bricks => "bricks",
            Pattern::Planks => "planks",
            Pattern::Tiles => "tiles",
            Pattern::Cables => "cables",
        }
    }
}

/// Torus side of periodic scenes, in scene units: a whole number of every
/// pattern's period (bricks 64 × 64 for two courses, planks 128 × 24·k…).
/// 384 = 6·64 = 3·128 = 16·24 = 12·32.
pub const TORUS: f64 = 384.0;

/// A scene: a pattern, a seed, and whether it wraps on the [`TORUS`].
#[derive(Clone, Copy, Debug)]
pub struct Scene {
    pub pattern: Pattern,
    pub seed: u64,
    pub periodic: bool,
    /// Amplitude of a fine surface texture (pores, scratches, weathering)
    /// on every material, in cells of 1.5 units: 0 for clean surfaces,
    /// about 0.15 for a rough wall whose grain rivals its mortar lines.
    pub rough: f64,
}

/// A hash of two integers and a seed into [0, 1).
fn hash(i: i64, j: i64, seed: u64) -> f64 {
    let mut z = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
        ^ seed.wrapping_mul(0x1656_67b1_9e37_79f9);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Scene {
    /// Index `i` wrapped to `n` cells when the scene is periodic.
    fn wrap(&self, i: i64, n: i64) -> i64 {
        if self.periodic { i.rem_euclid(n) } else { i }
    }

    /// Smooth value noise in [−1, 1] with cells of `cell` units (`TORUS` a
    /// whole number of them), anisotropic by `stretch` along u.
    fn noise(&self, u: f64, v: f64, cell: f64, stretch: f64, salt: u64) -> f64 {
        let (cu, cv) = (cell * stretch, cell);
        let (nu, nv) = ((TORUS / cu).round() as i64, (TORUS / cv).round() as i64);
        let (fu, fv) = (u / cu, v / cv);
        let (i, j) = (fu.floor() as i64, fv.floor() as i64);
        let s = |t: f64| t * t * (3.0 - 2.0 * t);
        let (tu, tv) = (s(fu - fu.floor()), s(fv - fv.floor()));
        let at = |a: i64, b: i64| 2.0 * hash(self.wrap(a, nu), self.wrap(b, nv), self.seed ^ salt) - 1.0;
        let top = at(i, j) + tu * (at(i + 1, j) - at(i, j));
        let bottom = at(i, j + 1) + tu * (at(i + 1, j + 1) - at(i, j + 1));
        top + tv * (bottom - top)
    }

    /// Two octaves of [`noise`](Self::noise).
    fn fbm(&self, u: f64, v: f64, cell: f64, stretch: f64, salt: u64) -> f64 {
        0.67 * self.noise(u, v, cell, stretch, salt) + 0.33 * self.noise(u, v, cell / 2.0, stretch, salt + 1)
    }

    /// The colour at scene point (u, v), each channel in about [0, 1].
    pub fn color(&self, u: f64, v: f64) -> [f64; 3] {
        let c = match self.pattern {
            Pattern::Bricks => self.bricks(u, v),
            Pattern::Planks => self.planks(u, v),
            Pattern::Tiles => self.tiles(u, v),
            Pattern::Cables => self.cables(u, v),
        };
        if self.rough == 0.0 {
            return c;
        }
        let grain = 1.0 + self.rough * (self.noise(u, v, 1.5, 1.0, 51) + 0.5 * self.noise(u, v, 3.0, 1.0, 52));
        c.map(|c| c * grain)
    }

    fn bricks(&self, u: f64, v: f64) -> [f64; 3] {
        let (bw, bh, mortar) = (64.0, 32.0, 5.0);
        let j = (v / bh).floor();
        let offset = if (j as i64).rem_euclid(2) == 1 { bw / 2.0 } else { 0.0 };
        let i = ((u - offset) / bw).floor();
        let (lu, lv) = (u - offset - i * bw, v - j * bh);
        let dist = lu.min(bw - lu).min(lv).min(bh - lv);
        let brick = smoothstep(mortar / 2.0 - 0.6, mortar / 2.0 + 0.6, dist);
        let id = hash(self.wrap(i as i64, (TORUS / bw) as i64), self.wrap(j as i64, (TORUS / bh) as i64), self.seed);
        let grain = 0.06 * self.fbm(u, v, 6.0, 1.0, 11);
        // Bevel lit from above: the top edge bright, the bottom edge dark.
        let bevel = 0.12 * (1.0 - smoothstep(mortar / 2.0, mortar / 2.0 + 3.0, lv))
            - 0.12 * (1.0 - smoothstep(mortar / 2.0, mortar / 2.0 + 3.0, bh - lv));
        let b = 0.45 + 0.2 * (id - 0.5) + grain + bevel * brick;
        let m = 0.78 + 0.04 * self.noise(u, v, 3.0, 1.0, 12);
        let t = brick;
        [t * b * 1.25 + (1.0 - t) * m, t * b * 0.7 + (1.0 - t) * m, t * b * 0.55 + (1.0 - t) * m * 0.95]
    }

    fn planks(&self, u: f64, v: f64) -> [f64; 3] {
        let (pw, len, gap) = (24.0, 128.0, 2.5);
        let rows = (TORUS / pw) as i64;
        let j = (v / pw).floor();
        // Staggered ends: each row's ends at a whole eighth of the length.
        let shift = (hash(self.wrap(j as i64, rows), 7, self.seed) * 8.0).floor() * len / 8.0;
        let i = ((u - shift) / len).floor();
        let (lu, lv) = (u - shift - i * len, v - j * pw);
        let dist = lu.min(len - lu).min(lv).min(pw - lv);
        let wood = smoothstep(gap / 2.0 - 0.5, gap / 2.0 + 0.5, dist);
        let id = hash(self.wrap(i as i64, (TORUS / len) as i64), self.wrap(j as i64, rows), self.seed ^ 3);
        let grain = 0.08 * (TAU * (lv / 5.0 + 0.8 * self.fbm(u, v, 12.0, 4.0, 21))).sin();
        let w = 0.55 + 0.15 * (id - 0.5) + grain;
        let g = 0.12;
        let t = wood;
        [t * w * 1.2 + (1.0 - t) * g, t * w * 0.9 + (1.0 - t) * g, t * w * 0.6 + (1.0 - t) * g]
    }

    fn tiles(&self, u: f64, v: f64) -> [f64; 3] {
        let (size, grout) = (32.0, 3.0);
        let (i, j) = ((u / size).floor(), (v / size).floor());
        let (lu, lv) = (u - i * size, v - j * size);
        let dist = lu.min(size - lu).min(lv).min(size - lv);
        let tile = smoothstep(grout / 2.0 - 0.5, grout / 2.0 + 0.5, dist);
        let n = (TORUS / size) as i64;
        let id = hash(self.wrap(i as i64, n), self.wrap(j as i64, n), self.seed);
        // A glaze: a soft highlight across each tile, and a little mottling.
        let glaze = 0.08 * ((lu + lv) / (2.0 * size) - 0.5) + 0.03 * self.noise(u, v, 8.0, 1.0, 31);
        let c = 0.72 + 0.1 * (id - 0.5) + glaze;
        let g = 0.3 + 0.03 * self.noise(u, v, 4.0, 1.0, 32);
        let t = tile;
        [t * c * 0.85 + (1.0 - t) * g, t * c * 0.95 + (1.0 - t) * g, t * c + (1.0 - t) * g]
    }

    fn cables(&self, u: f64, v: f64) -> [f64; 3] {
        let (spacing, thick) = (32.0, 5.0);
        let n = (TORUS / spacing) as i64;
        let wall = 0.6 + 0.08 * self.fbm(u, v, 16.0, 1.0, 41);
        // Each cable sags with its own phase and depth, period TORUS / 2 along u.
        let j = (v / spacing).floor();
        let mut shade: f64 = 1.0;
        for dj in -1..=1 {
            let c = j + f64::from(dj);
            let id = self.wrap(c as i64, n);
            let (phase, depth) = (hash(id, 1, self.seed), 3.0 + 6.0 * hash(id, 2, self.seed));
            let centre = (c + 0.5) * spacing + depth * (TAU * u / (TORUS / 2.0) + TAU * phase).sin();
            let d = (v - centre).abs();
            let core = 1.0 - smoothstep(thick / 2.0 - 0.6, thick / 2.0 + 0.6, d);
            // A highlight along the cable's upper side.
            let light = 0.25 * (-((v - centre + thick / 4.0) / 0.8).powi(2)).exp();
            shade = shade.min(1.0 - core * (0.8 - light));
        }
        [wall * shade, wall * shade * 0.97, wall * shade * 0.9]
    }
}

/// How a photo looks at its scene.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Rotation of the scene in the picture, degrees.
    pub angle: f64,
    /// Keystone: the projective terms (x and y), about ±0.3 for a
    /// noticeably oblique view, 0 for a square one.
    pub keystone: (f64, f64),
    /// Scene units per texel at the centre.
    pub zoom: f64,
    /// How unevenly the light falls: a gradient of about ± this across the
    /// picture, and a vignette of half of it. 0.25 for a casual photo.
    pub light: f64,
    /// Standard deviation of the sensor noise, 0.015 for a fair camera.
    pub noise: f64,
    /// The surface's fine texture, [`Scene::rough`].
    pub rough: f64,
}

impl Camera {
    /// A fair photo at `angle` degrees: mild keystone, light and noise.
    pub fn at(angle: f64) -> Camera {
        Camera { angle, keystone: (0.12, -0.08), zoom: 1.0, light: 0.25, noise: 0.015, rough: 0.1 }
    }
}

/// A gray or RGB image in [0, 1], planes row-major.
pub struct Rendered {
    pub planes: Vec<Vec<f32>>,
    pub width: usize,
    pub height: usize,
}

/// Renders `w` × `h` texels, each the mean of 2×2 samples of
/// `point(x, y)` → scene point, times `light(x, y)`, plus Gaussian-ish
/// sensor noise of standard deviation `noise`; `rgb` or luma.
fn render(
    scene: &Scene,
    w: usize,
    h: usize,
    rgb: bool,
    noise: f64,
    point: impl Fn(f64, f64) -> (f64, f64),
    light: impl Fn(f64, f64) -> f64,
) -> Rendered {
    let channels = if rgb { 3 } else { 1 };
    let mut planes = vec![Vec::with_capacity(w * h); channels];
    let mut rng = Rng(scene.seed ^ 0x5eed);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f64; 3];
            for (sx, sy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                let (px, py) = (x as f64 + sx, y as f64 + sy);
                let (u, v) = point(px, py);
                let c = scene.color(u, v);
                let l = light(px, py);
                for (s, c) in sum.iter_mut().zip(c) {
                    *s += 0.25 * c * l;
                }
            }
            // Sum of three uniforms: near-Gaussian, unit variance.
            let n = noise * (rng.next() + rng.next() + rng.next() - 1.5) * 2.0;
            if rgb {
                for (p, s) in planes.iter_mut().zip(sum) {
                    p.push((s + n).clamp(0.0, 1.0) as f32);
                }
            } else {
                let luma = 0.2126 * sum[0] + 0.7152 * sum[1] + 0.0722 * sum[2];
                planes[0].push((luma + n).clamp(0.0, 1.0) as f32);
            }
        }
    }
    Rendered { planes, width: w, height: h }
}

/// A photo of an unbounded `pattern` scene: a `w` × `h` window seen through
/// `camera`, at a place chosen by `seed`, with a light falling off across
/// it and sensor noise. It does not tile.
pub fn photo(pattern: Pattern, w: usize, h: usize, camera: Camera, seed: u64, rgb: bool) -> Rendered {
    let scene = Scene { pattern, seed, periodic: false, rough: camera.rough };
    let mut rng = Rng(seed);
    let origin = (1000.0 + 5000.0 * rng.next(), 1000.0 + 5000.0 * rng.next());
    let (sin, cos) = camera.angle.to_radians().sin_cos();
    let (cx, cy, half) = (w as f64 / 2.0, h as f64 / 2.0, w.max(h) as f64 / 2.0);
    let (kx, ky) = camera.keystone;
    let point = |x: f64, y: f64| {
        let (nx, ny) = ((x - cx) / half, (y - cy) / half);
        let depth = 1.0 + kx * nx + ky * ny;
        let (dx, dy) = ((x - cx) * camera.zoom / depth, (y - cy) * camera.zoom / depth);
        (origin.0 + cos * dx - sin * dy, origin.1 + sin * dx + cos * dy)
    };
    let (gx, gy) = (rng.next() - 0.5, rng.next() - 0.5);
    let light = |x: f64, y: f64| {
        let (nx, ny) = ((x - cx) / half, (y - cy) / half);
        (1.0 + camera.light * (gx * nx + gy * ny)) * (1.0 - 0.5 * camera.light * (nx * nx + ny * ny))
    };
    render(&scene, w, h, rgb, camera.noise, point, light)
}

/// How a periodic texture maps onto the torus (see the module docs).
#[derive(Clone, Copy, Debug)]
pub enum Wrap {
    /// Rotation by atan(q/p), scale √(p² + q²) periods across the image.
    Rotate { p: i64, q: i64 },
    /// Shear: lines of constant v at angle atan(k·H/W).
    Shear { k: i64 },
}

/// How a periodic texture is rendered.
#[derive(Clone, Copy, Debug)]
pub struct Look {
    /// RGB, or luma only.
    pub rgb: bool,
    /// Standard deviation of the per-texel noise.
    pub noise: f64,
    /// The surface's fine texture, [`Scene::rough`].
    pub rough: f64,
}

/// An exactly periodic `w` × `h` texture of `pattern` (see the module docs),
/// shifted by a seed-chosen offset so the wrap falls anywhere, with sensor
/// noise. It tiles on both axes.
pub fn texture(pattern: Pattern, w: usize, h: usize, wrap: Wrap, seed: u64, look: Look) -> Rendered {
    let Look { rgb, noise, rough } = look;
    let scene = Scene { pattern, seed, periodic: true, rough };
    let mut rng = Rng(seed);
    let (ou, ov) = (TORUS * rng.next(), TORUS * rng.next());
    let (wf, hf) = (w as f64, h as f64);
    let point = move |x: f64, y: f64| {
        let (a, b) = (x / wf, y / hf);
        let (u, v) = match wrap {
            Wrap::Rotate { p, q } => (p as f64 * a - q as f64 * b, q as f64 * a + p as f64 * b),
            Wrap::Shear { k } => (a, k as f64 * a + b),
        };
        (ou + TORUS * u, ov + TORUS * v)
    };
    render(&scene, w, h, rgb, noise, point, |_, _| 1.0)
}

impl Rendered {
    /// The planes as the slices `check` takes.
    pub fn refs(&self) -> Vec<&[f32]> {
        self.planes.iter().map(Vec::as_slice).collect()
    }
}

impl Rendered {
    /// Rounded to `bits`-bit integers, as a file would hold it.
    pub fn quantized(mut self, bits: u32) -> Rendered {
        for p in &mut self.planes {
            *p = super::quantize(p, bits);
        }
        self
    }

    /// The luma of an RGB image (0.2126 R + 0.7152 G + 0.0722 B), or the
    /// gray plane.
    pub fn luma(&self) -> Vec<f32> {
        match &self.planes[..] {
            [r, g, b, ..] => r.iter().zip(g).zip(b).map(|((r, g), b)| 0.2126 * r + 0.7152 * g + 0.0722 * b).collect(),
            [gray, ..] => gray.clone(),
            [] => Vec::new(),
        }
    }
}
