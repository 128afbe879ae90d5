//! The blend (`normalfit::blend`) against its formulas written out plainly
//! here in f64, on random unit normals; its identities (a flat map blended
//! in changes nothing; RNM of two tilts in one plane adds their angles);
//! the detail tiled, sizes that do not divide refused; the conventions.

use normalfit::Convention;
use normalfit::blend::{BlendOptions, Method, blend, blend_normal, repeats};
use normalfit::height::ConventionChoice;

use crate::common::rng::Rng;

/// A random unit normal of the upper hemisphere with z ≥ 0.2.
fn random_normal(rng: &mut Rng) -> [f64; 3] {
    loop {
        let v = [2.0 * rng.next() - 1.0, 2.0 * rng.next() - 1.0, rng.next()];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if l > 0.1 && v[2] / l >= 0.2 {
            return v.map(|c| c / l);
        }
    }
}

fn norm(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The formulas of "Blending in Detail" (Barré-Brisebois & Hill, 2012),
/// as the article writes them, on unit n1 (base) and n2 (detail).
fn reference(n1: [f64; 3], n2: [f64; 3], method: Method) -> [f64; 3] {
    match method {
        Method::Linear => norm([n1[0] + n2[0], n1[1] + n2[1], n1[2] + n2[2]]),
        Method::Udn => norm([n1[0] + n2[0], n1[1] + n2[1], n1[2]]),
        Method::Whiteout => norm([n1[0] + n2[0], n1[1] + n2[1], n1[2] * n2[2]]),
        Method::Rnm => {
            let t = [n1[0], n1[1], n1[2] + 1.0];
            let u = [-n2[0], -n2[1], n2[2]];
            let k = dot(t, u) / t[2];
            [t[0] * k - u[0], t[1] * k - u[1], t[2] * k - u[2]]
        }
        _ => unreachable!(),
    }
}

const METHODS: [Method; 4] = [Method::Rnm, Method::Whiteout, Method::Udn, Method::Linear];

fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
}

#[test]
fn blend_matches_the_formulas_on_random_unit_normals() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (w, h) = (64, 48);
    let base: Vec<[f64; 3]> = (0..w * h).map(|_| random_normal(&mut rng)).collect();
    let detail: Vec<[f64; 3]> = (0..w * h).map(|_| random_normal(&mut rng)).collect();
    for method in METHODS {
        let opts = BlendOptions::new().with_method(method).with_convention(ConventionChoice::OpenGl);
        let (out, report) = blend::<f64, [f64; 3]>(&base, (w, h), &detail, (w, h), &opts).unwrap();
        assert_eq!(report.repeats, (1, 1));
        for k in 0..w * h {
            let want = reference(base[k], detail[k], method);
            assert!(close(out[k], want, 1e-12), "{method} texel {k}: {:?} vs {want:?}", out[k]);
            assert!((dot(out[k], out[k]) - 1.0).abs() < 1e-12, "{method}: unit");
        }
    }
}

#[test]
fn blend_strength_scales_the_detail_slopes() {
    let mut rng = Rng(7);
    for _ in 0..1000 {
        let (b, d) = (random_normal(&mut rng), random_normal(&mut rng));
        let f = 3.0 * rng.next();
        let scaled = norm([f * d[0], f * d[1], d[2]]);
        for method in METHODS {
            assert!(close(blend_normal(b, d, method, f), reference(b, scaled, method), 1e-12));
        }
        // Strength 0 leaves the base (linear averages it with flat).
        for method in [Method::Rnm, Method::Whiteout, Method::Udn] {
            assert!(close(blend_normal(b, d, method, 0.0), b, 1e-12), "{method}");
        }
    }
}

#[test]
fn blend_a_flat_map_is_the_identity() {
    let mut rng = Rng(11);
    let flat = [0.0, 0.0, 1.0];
    for _ in 0..1000 {
        let n = random_normal(&mut rng);
        // A flat detail gives the base back (linear halves its tilt).
        for method in [Method::Rnm, Method::Whiteout, Method::Udn] {
            assert!(close(blend_normal(n, flat, method, 1.0), n, 1e-12), "{method} flat detail");
        }
        // A flat base gives the detail back for RNM and whiteout.
        for method in [Method::Rnm, Method::Whiteout] {
            assert!(close(blend_normal(flat, n, method, 1.0), n, 1e-12), "{method} flat base");
        }
    }
}

#[test]
fn blend_rnm_of_two_tilts_adds_their_angles() {
    // Two normals tilted in the same plane by a and b: the detail rotated
    // onto the base is tilted by a + b (the article's motivating case,
    // where UDN and whiteout fall short).
    for (a, b) in [(0.3f64, 0.4f64), (0.5, -0.2), (0.1, 0.9), (-0.7, -0.3)] {
        let base = [a.sin(), 0.0, a.cos()];
        let detail = [b.sin(), 0.0, b.cos()];
        let got = blend_normal(base, detail, Method::Rnm, 1.0);
        let want = [(a + b).sin(), 0.0, (a + b).cos()];
        assert!(close(got, want, 1e-12), "{a} + {b}: {got:?}");
        // The same along y.
        let got = blend_normal([0.0, a.sin(), a.cos()], [0.0, b.sin(), b.cos()], Method::Rnm, 1.0);
        assert!(close(got, [0.0, (a + b).sin(), (a + b).cos()], 1e-12));
    }
    // Whiteout and UDN do not add the angles.
    let (a, b) = (0.5f64, 0.5f64);
    let udn = blend_normal([a.sin(), 0.0, a.cos()], [b.sin(), 0.0, b.cos()], Method::Udn, 1.0);
    assert!(udn[0] < (a + b).sin() - 0.05, "{udn:?}");
}

#[test]
fn blend_tiles_a_smaller_detail_and_refuses_sizes_that_do_not_divide() {
    let mut rng = Rng(5);
    let (bw, bh, dw, dh) = (12, 8, 4, 2);
    let base: Vec<[f64; 3]> = (0..bw * bh).map(|_| random_normal(&mut rng)).collect();
    let detail: Vec<[f64; 3]> = (0..dw * dh).map(|_| random_normal(&mut rng)).collect();
    let opts = BlendOptions::new().with_convention(ConventionChoice::DirectX);
    let (out, report) = blend::<f64, [f64; 3]>(&base, (bw, bh), &detail, (dw, dh), &opts).unwrap();
    assert_eq!(report.repeats, (3, 4));
    for y in 0..bh {
        for x in 0..bw {
            let want = reference(base[y * bw + x], detail[(y % dh) * dw + x % dw], Method::Rnm);
            assert!(close(out[y * bw + x], want, 1e-12));
        }
    }
    assert!(repeats((12, 8), (5, 2)).is_err());
    assert!(repeats((12, 8), (4, 3)).is_err());
    assert!(repeats((12, 8), (24, 8)).is_err());
    let five: Vec<[f64; 3]> = (0..10).map(|_| random_normal(&mut rng)).collect();
    let e = blend::<f64, [f64; 3]>(&base, (bw, bh), &five, (5, 2), &opts).unwrap_err();
    assert!(e.to_string().contains("must divide"), "{e}");
    // A bad strength is an option error.
    let bad = opts.with_strength(f64::NAN);
    assert!(blend::<f64, [f64; 3]>(&base, (bw, bh), &detail, (dw, dh), &bad).is_err());
    // A NaN normal names its texel.
    let mut nan = base.clone();
    nan[bw + 2][1] = f64::NAN;
    let e = blend::<f64, [f64; 3]>(&nan, (bw, bh), &detail, (dw, dh), &opts).unwrap_err();
    assert!(e.to_string().contains("(x 2, y 1)"), "{e}");
}

/// The normals of heights z(x, y) by central differences, wrapping, in the
/// convention `c` (OpenGL: +y up, so ny = +∂z/∂row).
fn normals_of(w: usize, h: usize, c: Convention, z: impl Fn(f64, f64) -> f64) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f64, y as f64);
            let gx = (z(fx + 1.0, fy) - z(fx - 1.0, fy)) / 2.0;
            let gy = (z(fx, fy + 1.0) - z(fx, fy - 1.0)) / 2.0;
            let sigma = if c == Convention::OpenGl { -1.0 } else { 1.0 };
            out.push(norm([-gx, -sigma * gy, 1.0]));
        }
    }
    out
}

#[test]
fn blend_flips_a_detail_of_the_other_convention() {
    let (w, h) = (128, 128);
    let tau = std::f64::consts::TAU;
    let surface =
        |x: f64, y: f64| 6.0 * (tau * x / 64.0).sin() * (tau * y / 32.0).cos() + 3.0 * (tau * (x + y) / 128.0).sin();
    let ripple = |x: f64, y: f64| 2.0 * (tau * (2.0 * x + y) / 64.0).cos() * (tau * y / 64.0).sin();
    let base = normals_of(w, h, Convention::OpenGl, surface);
    let detail_gl = normals_of(w, h, Convention::OpenGl, ripple);
    let detail_dx = normals_of(w, h, Convention::DirectX, ripple);
    let auto = BlendOptions::new();
    let (want, r) = blend::<f64, [f64; 3]>(&base, (w, h), &detail_gl, (w, h), &auto).unwrap();
    assert_eq!((r.base, r.detail), (Convention::OpenGl, Convention::OpenGl));
    // Detected: the DirectX detail is flipped to the base's convention.
    let (got, r) = blend::<f64, [f64; 3]>(&base, (w, h), &detail_dx, (w, h), &auto).unwrap();
    assert_eq!((r.base, r.detail), (Convention::OpenGl, Convention::DirectX));
    assert!(r.detail_guess.unwrap().confident);
    assert!(want.iter().zip(&got).all(|(a, b)| close(*a, *b, 1e-12)));
    // Stated: the same.
    let stated =
        BlendOptions::new().with_convention(ConventionChoice::OpenGl).with_detail_convention(ConventionChoice::DirectX);
    let (got, _) = blend::<f64, [f64; 3]>(&base, (w, h), &detail_dx, (w, h), &stated).unwrap();
    assert!(want.iter().zip(&got).all(|(a, b)| close(*a, *b, 1e-12)));
    // Both in DirectX: the result is the OpenGL blend with its green negated.
    let base_dx = normals_of(w, h, Convention::DirectX, surface);
    let (dx, r) = blend::<f64, [f64; 3]>(&base_dx, (w, h), &detail_dx, (w, h), &auto).unwrap();
    assert_eq!((r.base, r.detail), (Convention::DirectX, Convention::DirectX));
    assert!(want.iter().zip(&dx).all(|(a, b)| close(*a, [b[0], -b[1], b[2]], 1e-12)));
}

#[test]
fn blend_into_encoded_texels_rounds_the_float_result() {
    let mut rng = Rng(3);
    let (w, h) = (16, 16);
    let base: Vec<[f32; 3]> = (0..w * h).map(|_| random_normal(&mut rng).map(|c| c as f32)).collect();
    let detail: Vec<[f32; 3]> = (0..w * h).map(|_| random_normal(&mut rng).map(|c| c as f32)).collect();
    let opts = BlendOptions::new().with_method(Method::Whiteout).with_convention(ConventionChoice::OpenGl);
    let (f, _) = blend::<f32, [f64; 3]>(&base, (w, h), &detail, (w, h), &opts).unwrap();
    let (e8, _) = blend::<f32, [u8; 3]>(&base, (w, h), &detail, (w, h), &opts).unwrap();
    let (e16, _) = blend::<f32, [u16; 3]>(&base, (w, h), &detail, (w, h), &opts).unwrap();
    for k in 0..w * h {
        for c in 0..3 {
            let code = (f[k][c] + 1.0) / 2.0;
            assert!((f64::from(e8[k][c]) - 255.0 * code).abs() <= 0.5 + 1e-9);
            assert!((f64::from(e16[k][c]) - 65535.0 * code).abs() <= 0.5 + 1e-6);
        }
    }
}
