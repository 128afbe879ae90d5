//! `normalfit::check` on maps made here: the convention guessed from the
//! curl is right on every map where it is confident (fitted maps of both
//! conventions, several surfaces, patch sizes and depths; noise, which
//! cannot tell), and on the real sets of `../shared/data`; lengths,
//! negative z, the RG layout, banding, and the repair.

use std::path::{Path, PathBuf};

use normalfit::check::{CheckOptions, MapLayout, check_file, convention, write_fixed};
use normalfit::convert::Output;
use normalfit::height::ConventionChoice;
use normalfit::io::{Encoding, ReadOptions, encode_normals, read_path};
use normalfit::{Convention, Fit, FromNormal, Options, Strength, normal_map, normals};

use crate::common::rng::Rng;
use crate::common::shared_data::data_dir;

const W: usize = 128;
const H: usize = 96;

/// Height maps: smooth waves, a field of bumps, steps (bricks), noise.
fn surfaces() -> Vec<(&'static str, Vec<f64>)> {
    let tau = std::f64::consts::TAU;
    let at = |f: &dyn Fn(f64, f64) -> f64| -> Vec<f64> {
        (0..W * H).map(|k| f((k % W) as f64 / W as f64, (k / W) as f64 / H as f64)).collect()
    };
    let mut rng = Rng(42);
    let noise: Vec<f64> = (0..W * H).map(|_| rng.next()).collect();
    vec![
        ("waves", at(&|u, v| 0.5 + 0.3 * (tau * (2.0 * u + v)).sin() + 0.2 * (tau * 3.0 * v).cos())),
        ("bumps", at(&|u, v| ((tau * 4.0 * u).sin() * (tau * 3.0 * v).sin()).max(0.0).powi(2))),
        (
            "bricks",
            at(&|u, v| {
                let row = (v * 6.0).floor();
                let x = (u * 4.0 + 0.5 * row).fract();
                if x < 0.08 || (v * 6.0).fract() < 0.12 { 0.0 } else { 1.0 }
            }),
        ),
        ("noise", noise),
    ]
}

fn write_png<T: normalfit::io::NormalTexel>(path: &Path, texels: &[T], encoding: &Encoding) {
    let file = std::fs::File::create(path).unwrap();
    encode_normals(texels, None, W, H, encoding, std::io::BufWriter::new(file)).unwrap();
}

/// The fitted normal map of `heights` in `convention`, encoded in `bits`.
fn fitted(dir: &Path, name: &str, heights: &[f64], opts: &Options, bits: u8) -> PathBuf {
    let n: Vec<[f64; 3]> = normals(heights, W, H, opts).unwrap().iter().map(|v| v.map(f64::from)).collect();
    let path = dir.join(format!("{name}.{}", if bits == 32 { "exr" } else { "png" }));
    match bits {
        8 => write_png(&path, &n.iter().map(|&v| <[u8; 3]>::from_normal(v)).collect::<Vec<_>>(), &Encoding::png8()),
        16 => write_png(&path, &n.iter().map(|&v| <[u16; 3]>::from_normal(v)).collect::<Vec<_>>(), &Encoding::png16()),
        _ => write_png(&path, &n.iter().map(|&v| <[f32; 3]>::from_normal(v)).collect::<Vec<_>>(), &Encoding::exr()),
    }
    path
}

#[test]
fn check_guesses_the_convention_of_generated_maps_when_confident() {
    let dir = tempfile::tempdir().unwrap();
    let (mut confident, mut total, mut wrong, mut unsure) = (0, 0, Vec::new(), Vec::new());
    for (name, heights) in surfaces() {
        for convention in [Convention::OpenGl, Convention::DirectX] {
            for (n, fit) in [(3, Fit::Orthogonal), (5, Fit::Vertical), (9, Fit::Orthogonal)] {
                for scale in [2.0, 20.0] {
                    for bits in [8, 16, 32] {
                        let opts = Options::new()
                            .with_patch(n)
                            .with_fit(fit)
                            .with_convention(convention)
                            .with_strength(Strength::Scale(scale));
                        let label = format!("{name}_{convention}_{n}_{fit}_{scale}_{bits}");
                        let path = fitted(dir.path(), &label, &heights, &opts, bits);
                        let report = check_file(&path, &ReadOptions::default(), &CheckOptions::new()).unwrap();
                        let g = report.guess;
                        total += 1;
                        if g.confident {
                            confident += 1;
                            if g.convention != convention {
                                wrong.push(format!("{label}: {g:?}"));
                            }
                        }
                        // Smooth surfaces at 16 bits or float: the guess is sure.
                        if (name == "waves" || name == "bumps") && bits != 8 && !g.confident {
                            unsure.push(format!("{label}: {g:?}"));
                        }
                    }
                }
            }
        }
    }
    println!("confident on {confident} of {total} generated maps");
    assert!(wrong.is_empty(), "confidently wrong: {wrong:#?}");
    assert!(unsure.is_empty(), "smooth maps not told: {unsure:#?}");
}

#[test]
fn check_convention_of_noise_is_not_confident() {
    let mut rng = Rng(9);
    for _ in 0..8 {
        let normals: Vec<[f64; 3]> = (0..W * H)
            .map(|_| {
                let v = [rng.next() - 0.5, rng.next() - 0.5, 1.0];
                let l = (v[0] * v[0] + v[1] * v[1] + 1.0f64).sqrt();
                v.map(|c| c / l)
            })
            .collect();
        let g = convention::guess(&normals, W, H).unwrap();
        assert!(!g.confident, "{g:?}");
    }
    // A flat map cannot tell either.
    let flat = vec![[0.0f64, 0.0, 1.0]; W * H];
    let g = convention::guess(&flat, W, H).unwrap();
    assert!(!g.confident && g.convention == Convention::OpenGl, "{g:?}");
}

#[test]
fn check_finds_lengths_negative_z_and_rg_and_the_fix_repairs_them() {
    let dir = tempfile::tempdir().unwrap();
    let heights = &surfaces()[0].1;
    let opts = Options::new().with_strength(Strength::Scale(8.0));
    let n: Vec<[f64; 3]> = normals(heights, W, H, &opts).unwrap().iter().map(|v| v.map(f64::from)).collect();
    let read = ReadOptions::default();

    // Clean: the fitted map, 8 and 16 bits.
    for bits in [8, 16] {
        let path = fitted(dir.path(), &format!("clean{bits}"), heights, &opts, bits);
        let r = check_file(&path, &read, &CheckOptions::new()).unwrap();
        assert_eq!((r.off_length, r.negative_z, r.layout), (0, 0, MapLayout::Rgb), "{bits}: {r:?}");
        assert!(r.clean(), "{bits}: {:?}", r.findings());
        assert_eq!(r.guess.convention, Convention::OpenGl);
    }

    // Shortened normals (0.9 of unit), and some pointing into the surface.
    let short: Vec<[u16; 3]> = n
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let s = if k % 10 == 0 { 0.9 } else { 1.0 };
            let z = if k % 50 == 1 { -v[2] } else { v[2] };
            <[u16; 3]>::from_normal([s * v[0], s * v[1], s * z])
        })
        .collect();
    let path = dir.path().join("short.png");
    write_png(&path, &short, &Encoding::png16());
    let r = check_file(&path, &read, &CheckOptions::new()).unwrap();
    assert_eq!(r.off_length, (0..W * H).filter(|k| k % 10 == 0).count());
    assert_eq!(r.negative_z, (0..W * H).filter(|k| k % 50 == 1).count());
    let names: Vec<&str> = r.findings().iter().map(|f| f.name()).collect();
    assert_eq!(names, ["length", "negative_z"]);
    // Repaired: unit again.
    let fixed = dir.path().join("short_fixed.png");
    let raster = read_path(&path, &read).unwrap();
    write_fixed(&raster, &r, false, &Default::default(), Output::file(&fixed), Some(&path)).unwrap();
    let again = check_file(&fixed, &read, &CheckOptions::new()).unwrap();
    assert_eq!(again.off_length, 0);

    // Two channels: B = 0 everywhere.
    let rg: Vec<[u8; 3]> = n.iter().map(|&v| <[u8; 3]>::from_normal(v)).map(|t| [t[0], t[1], 0]).collect();
    let path = dir.path().join("rg.png");
    write_png(&path, &rg, &Encoding::png8());
    let r = check_file(&path, &read, &CheckOptions::new()).unwrap();
    assert_eq!((r.layout, r.off_length, r.negative_z), (MapLayout::Rg, 0, 0), "{r:?}");
    assert_eq!(r.findings().iter().map(|f| f.name()).collect::<Vec<_>>(), ["rg"]);
    assert!(r.guess.confident && r.guess.convention == Convention::OpenGl, "{:?}", r.guess);
    // z rebuilt: within 8-bit rounding of the original map.
    let fixed = dir.path().join("rg_fixed.png");
    let raster = read_path(&path, &read).unwrap();
    write_fixed(&raster, &r, false, &Default::default(), Output::file(&fixed), Some(&path)).unwrap();
    let back = normal_map::read(&fixed, &read, false).unwrap().2;
    let orig: Vec<[u8; 3]> = n.iter().map(|&v| <[u8; 3]>::from_normal(v)).collect();
    for (k, b) in back.iter().enumerate() {
        let want = orig[k].map(|c| 2.0 * f32::from(c) / 255.0 - 1.0);
        assert!((b[2] - want[2]).abs() < 0.03, "texel {k}: {b:?} vs {want:?}");
    }
    assert!(check_file(&fixed, &read, &CheckOptions::new()).unwrap().clean());
}

#[test]
fn check_fix_flips_green_to_the_convention_asked() {
    let dir = tempfile::tempdir().unwrap();
    let heights = &surfaces()[1].1;
    let gl = Options::new().with_strength(Strength::Scale(8.0));
    let dx = gl.clone().with_convention(Convention::DirectX);
    let read = ReadOptions::default();
    let dx_path = fitted(dir.path(), "dx", heights, &dx, 16);
    let gl_path = fitted(dir.path(), "gl", heights, &gl, 16);
    let r = check_file(&dx_path, &read, &CheckOptions::new()).unwrap();
    assert!(r.guess.confident && r.guess.convention == Convention::DirectX);
    let out = dir.path().join("to_gl.png");
    let raster = read_path(&dx_path, &read).unwrap();
    let fix = normalfit::check::FixOptions::new().with_to(Some(Convention::OpenGl));
    write_fixed(&raster, &r, false, &fix, Output::file(&out), Some(&dx_path)).unwrap();
    let (got, want) = (read_path(&out, &read).unwrap(), read_path(&gl_path, &read).unwrap());
    for c in ["R", "G", "B"] {
        let (a, b) = (got.plane(c).unwrap().data.to_f32().unwrap(), want.plane(c).unwrap().data.to_f32().unwrap());
        let worst = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
        assert!(worst <= 1.5 / 65535.0, "{c}: {worst}");
    }
    // Stating the expected convention: a confident other guess is a finding.
    let expect_gl = CheckOptions::new().with_convention(ConventionChoice::OpenGl);
    let r = check_file(&dx_path, &read, &expect_gl).unwrap();
    assert!(r.findings().iter().any(|f| f.name() == "convention"));
    // Flipping a map whose convention is unknown is refused.
    let mut rng = Rng(1);
    let noise: Vec<[u16; 3]> = (0..W * H)
        .map(|_| {
            let v = [rng.next() - 0.5, rng.next() - 0.5, 1.0];
            let l = (v[0] * v[0] + v[1] * v[1] + 1.0f64).sqrt();
            <[u16; 3]>::from_normal(v.map(|c| c / l))
        })
        .collect();
    let noise_path = dir.path().join("noise.png");
    write_png(&noise_path, &noise, &Encoding::png16());
    let r = check_file(&noise_path, &read, &CheckOptions::new()).unwrap();
    let raster = read_path(&noise_path, &read).unwrap();
    let out = dir.path().join("noise_fixed.png");
    let e = write_fixed(&raster, &r, false, &fix, Output::file(&out), Some(&noise_path)).unwrap_err();
    assert!(e.error.to_string().contains("cannot tell its convention"), "{}", e.error);
    assert!(!out.exists());
}

#[test]
fn check_finds_banding_in_8_bit_maps_of_smooth_surfaces() {
    let dir = tempfile::tempdir().unwrap();
    let tau = std::f64::consts::TAU;
    // One gentle wave across the map: slopes change slower than 8 bits follow.
    let smooth: Vec<f64> = (0..W * H)
        .map(|k| 0.5 * (tau * (k % W) as f64 / W as f64).sin() + 0.3 * (tau * (k / W) as f64 / H as f64).cos())
        .collect();
    let opts = Options::new().with_strength(Strength::Scale(2.0));
    let read = ReadOptions::default();
    let r8 = check_file(&fitted(dir.path(), "smooth8", &smooth, &opts, 8), &read, &CheckOptions::new()).unwrap();
    let b = r8.banding.unwrap();
    assert!(b.banded, "{b:?}");
    assert!(r8.findings().iter().any(|f| f.name() == "banding"));
    let r16 = check_file(&fitted(dir.path(), "smooth16", &smooth, &opts, 16), &read, &CheckOptions::new()).unwrap();
    assert!(r16.banding.is_none() && r16.clean(), "{:?}", r16.findings());
    // Rough surfaces at 8 bits: no banding.
    for (name, heights) in surfaces() {
        if name == "waves" {
            continue;
        }
        let opts = Options::new().with_strength(Strength::Scale(20.0));
        let r = check_file(&fitted(dir.path(), name, &heights, &opts, 8), &read, &CheckOptions::new()).unwrap();
        assert!(!r.banding.unwrap().banded, "{name}: {:?}", r.banding);
    }
}

/// The normal maps of ../shared/data with the convention their sets name.
fn real_maps() -> Vec<(PathBuf, Convention)> {
    let d = data_dir().join("tileable");
    vec![
        (d.join("ambientcg_Bricks061/Bricks061_1K-JPG_NormalGL.jpg"), Convention::OpenGl),
        (d.join("ambientcg_Bricks061/Bricks061_1K-JPG_NormalDX.jpg"), Convention::DirectX),
        (d.join("polyhaven_denim_fabric/denim_fabric_nor_gl_1k.png"), Convention::OpenGl),
        (d.join("materialx_adsk_bricks_02/bricks_02_normal_2k_raw.exr"), Convention::OpenGl),
        (d.join("materialx_adsk_bricks_02/bricks_02_normal_2k_raw.png"), Convention::OpenGl),
    ]
}

#[test]
#[ignore = "needs ../shared/data (the shared real textures); CI runs it with --include-ignored"]
fn check_guesses_the_convention_of_the_real_maps() {
    println!("| map | convention | guess | confident | confidence | curl as opengl | curl as directx |");
    println!("|---|---|---|---|---|---|---|");
    let mut wrong = Vec::new();
    let mut confident = 0;
    for (path, want) in real_maps() {
        let r = check_file(&path, &ReadOptions::default(), &CheckOptions::new()).unwrap();
        let g = r.guess;
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        println!(
            "| {name} | {want} | {} | {} | {:.3} | {:.4} | {:.4} |",
            g.convention, g.confident, g.confidence, g.curl[0], g.curl[1]
        );
        if g.confident {
            confident += 1;
            if g.convention != want {
                wrong.push(name);
            }
        }
    }
    assert!(wrong.is_empty(), "confidently wrong: {wrong:?}");
    // The guess tells them apart, not only abstains.
    assert!(confident >= 3, "confident on {confident} maps only");
}
