//! `normalfit shade` as users run it: lit views of height maps (through the
//! fit) and of normal maps (8/16-bit PNG, EXR in [0, 1] or signed), checked
//! against Lambert's law computed here; tiling, the light's direction,
//! outputs and errors.

use crate::common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::cli::{run, s};
use normalfit::io::{ExrDepth, ExrOptions, encode_normals};
use normalfit::shade::AMBIENT;

fn ok(out: &Output) {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// The one error line of a failed run (besides warnings and the summary
/// line of a run of many inputs); exit code 2.
fn error_line(out: &Output) -> String {
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!err.contains("panicked"), "{err}");
    let summary = |l: &str| l.contains(" shaded, ") && l.ends_with(" s");
    let lines: Vec<&str> = err.lines().filter(|l| !l.starts_with("normalfit: warning: ") && !summary(l)).collect();
    assert_eq!(lines.len(), 1, "want one error line, got {err:?}");
    lines[0].to_string()
}

/// A gray 8-bit picture as (width, height, values).
fn gray(path: &Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(img.color(), image::ColorType::L8, "shade writes 8-bit gray");
    let img = img.into_luma8();
    (img.width(), img.height(), img.into_raw())
}

/// Lambert's law as the `shade` module documents it, in [0, 255], not
/// rounded: the light towards (cos e cos a, cos e sin a, sin e), n in the
/// OpenGL frame (x right, y up the image), normalised here.
fn lambert(n: [f64; 3], azimuth_deg: f64, elevation_deg: f64) -> f64 {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    let l = [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let cos = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]) / len;
    255.0 * (AMBIENT + (1.0 - AMBIENT) * cos.max(0.0))
}

/// `got` is `want` rounded (to within float noise).
fn assert_rounds_to(got: u8, want: f64, what: &str) {
    assert!((f64::from(got) - want).abs() <= 0.5 + 1e-3, "{what}: got {got}, want {want:.3}");
}

fn write_gray16(path: &Path, w: u32, h: u32, value: impl Fn(u32, u32) -> u16) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| image::Luma([value(x, y)]))
        .save(path)
        .unwrap();
}

#[test]
fn a_tilted_plane_lights_as_lambert_says() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plane.png");
    let (w, h) = (24u32, 16u32);
    // Whole 16-bit steps, so the stored plane is exact.
    let (dx, dy) = (300.0, 200.0);
    write_gray16(&input, w, h, |x, y| (1000.0 + dx * f64::from(x) + dy * f64::from(y)) as u16);
    let scale = 50.0;
    // z = S·h grows by gx to the right and by gy down the image, so the
    // surface faces left and up: n ∝ (−gx, +gy, 1) with y up (OpenGL).
    let (gx, gy) = (scale * dx / 65535.0, scale * dy / 65535.0);
    let normal = [-gx, gy, 1.0];
    let out = dir.path().join("lit.png");
    for (azimuth, elevation) in [(135.0, 35.0), (200.0, 30.0), (0.0, 60.0), (90.0, 10.0), (-60.0, 45.0)] {
        let light = format!("{azimuth},{elevation}");
        for convention in ["gl", "dx"] {
            let args = ["shade", s(&input), "-o", s(&out), "-s", "50", "--border", "clamp"];
            ok(&run(&[&args[..], &["--light", &light, "--convention", convention]].concat()));
            let (ow, oh, lit) = gray(&out);
            assert_eq!((ow, oh), (w, h));
            let want = lambert(normal, azimuth, elevation);
            // Clamped borders flatten the edge texels' patches: the interior is the plane.
            for y in 1..h - 1 {
                for x in 1..w - 1 {
                    let got = lit[(y * w + x) as usize];
                    assert_rounds_to(got, want, &format!("light {light}, {convention}, texel ({x}, {y})"));
                }
            }
        }
    }
    // The default light is the library's, from the top-left at 35°.
    ok(&run(&["shade", s(&input), "-o", s(&out), "-s", "50", "--border", "clamp"]));
    assert_rounds_to(gray(&out).2[(5 * w + 5) as usize], lambert(normal, 135.0, 35.0), "default light");
}

/// A grid of tilted unit normals, azimuths all around so that the map
/// looks like a normal map (mean near +z).
fn known_normals(w: usize, h: usize) -> Vec<[f64; 3]> {
    (0..w * h)
        .map(|k| {
            let tilt = (5.0 + 35.0 * (k % 7) as f64 / 6.0).to_radians();
            let around = (k as f64 * 47.0).to_radians();
            [tilt.sin() * around.cos(), tilt.sin() * around.sin(), tilt.cos()]
        })
        .collect()
}

#[test]
fn normal_maps_light_their_stored_normals() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (12usize, 10usize);
    let normals = known_normals(w, h);
    let light = (160.0, 25.0);
    let light_arg = format!("{},{}", light.0, light.1);

    // Each stored map with the normals it holds, decoded here by c → 2c − 1
    // (or as stored for --signed); `flip_y` for green-down maps.
    let encode8 = |n: f64| (255.0 * (n + 1.0) / 2.0).round();
    let encode16 = |n: f64| (65535.0 * (n + 1.0) / 2.0).round();
    let png8 = dir.path().join("n8.png");
    let stored8: Vec<[f64; 3]> = normals.iter().map(|n| n.map(encode8)).collect();
    image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
        image::Rgb(stored8[y as usize * w + x as usize].map(|c| c as u8))
    })
    .save(&png8)
    .unwrap();
    let png16 = dir.path().join("n16.png");
    let stored16: Vec<[f64; 3]> = normals.iter().map(|n| n.map(encode16)).collect();
    image::ImageBuffer::<image::Rgb<u16>, Vec<u16>>::from_fn(w as u32, h as u32, |x, y| {
        image::Rgb(stored16[y as usize * w + x as usize].map(|c| c as u16))
    })
    .save(&png16)
    .unwrap();
    let png_dx = dir.path().join("dx.png");
    let stored_dx: Vec<[f64; 3]> = normals.iter().map(|&[x, y, z]| [x, -y, z].map(encode8)).collect();
    image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
        image::Rgb(stored_dx[y as usize * w + x as usize].map(|c| c as u8))
    })
    .save(&png_dx)
    .unwrap();
    let exr = |name: &str, texels: Vec<[f32; 3]>| {
        let path = dir.path().join(name);
        let mut bytes = std::io::Cursor::new(Vec::new());
        let as_given = ExrOptions::new(ExrDepth::Float).with_signed(true).into();
        encode_normals(&texels, None, w, h, &as_given, &mut bytes).unwrap();
        fs::write(&path, bytes.into_inner()).unwrap();
        path
    };
    let exr_unit = exr("unit.exr", normals.iter().map(|n| n.map(|c| ((c + 1.0) / 2.0) as f32)).collect());
    let exr_signed = exr("signed.exr", normals.iter().map(|n| n.map(|c| c as f32)).collect());

    let from_stored = |stored: &[[f64; 3]], top: f64, flip_y: bool| -> Vec<[f64; 3]> {
        stored
            .iter()
            .map(|c| {
                let [x, y, z] = c.map(|c| 2.0 * c / top - 1.0);
                [x, if flip_y { -y } else { y }, z]
            })
            .collect()
    };
    let as_f32 = |n: &[f64; 3]| n.map(|c| f64::from(c as f32));
    /// A stored map, the arguments that say how to read it, and the
    /// normals it holds as decoded here.
    struct Case<'a> {
        input: &'a Path,
        extra: &'a [&'a str],
        decoded: Vec<[f64; 3]>,
    }
    let case = |input, extra, decoded| Case { input, extra, decoded };
    let exr_unit_decoded = normals.iter().map(|n| n.map(|c| 2.0 * f64::from(((c + 1.0) / 2.0) as f32) - 1.0)).collect();
    let cases = [
        case(&png8, &[], from_stored(&stored8, 255.0, false)),
        case(&png16, &[], from_stored(&stored16, 65535.0, false)),
        case(&png_dx, &["--convention", "directx"], from_stored(&stored_dx, 255.0, true)),
        case(&exr_unit, &[], exr_unit_decoded),
        case(&exr_signed, &["--signed"], normals.iter().map(as_f32).collect()),
    ];
    for Case { input, extra, decoded } in cases {
        let out = dir.path().join("lit.png");
        let args = [&["shade", s(input), "--light", &light_arg][..], extra].concat();
        ok(&run(&[&args[..], &["-o", s(&out)]].concat()));
        let (ow, oh, lit) = gray(&out);
        assert_eq!((ow as usize, oh as usize), (w, h));
        for (k, (&got, n)) in lit.iter().zip(&decoded).enumerate() {
            assert_rounds_to(got, lambert(*n, light.0, light.1), &format!("{} texel {k}", input.display()));
        }
        // The kind was detected from the pixels: naming it changes nothing.
        let named = dir.path().join("named.png");
        ok(&run(&[&args[..], &["--kind", "normal", "-o", s(&named)]].concat()));
        assert_eq!(gray(&named).2, lit, "{}", input.display());
    }
}

/// A 16-bit height map with bumps and a slope, tileable or not.
fn write_bumpy(path: &Path, w: u32, h: u32) {
    write_gray16(path, w, h, |x, y| {
        let (u, v) = (f64::from(x) / f64::from(w), f64::from(y) / f64::from(h));
        let z = 0.5 + 0.2 * (u * 12.0).sin() * (v * 9.0).cos() + 0.1 * ((x * 7 + y * 3) % 5) as f64 / 5.0 + 0.1 * u;
        (z.clamp(0.0, 1.0) * 65535.0).round() as u16
    });
}

#[test]
fn tile_doubles_the_size_and_repeats_the_view() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    let (w, h) = (19u32, 13u32);
    write_bumpy(&input, w, h);
    let (plain, tiled) = (dir.path().join("plain.png"), dir.path().join("tiled.png"));
    ok(&run(&["shade", s(&input), "-s", "6", "--border", "mirror", "-o", s(&plain)]));
    ok(&run(&["shade", s(&input), "-s", "6", "--border", "mirror", "--tile", "-o", s(&tiled)]));
    let (_, _, one) = gray(&plain);
    let (tw, th, four) = gray(&tiled);
    assert_eq!((tw, th), (2 * w, 2 * h));
    assert!(one.iter().any(|&v| v != one[0]), "the view has detail to repeat");
    for y in 0..th {
        for x in 0..tw {
            assert_eq!(four[(y * tw + x) as usize], one[((y % h) * w + x % w) as usize], "({x}, {y})");
        }
    }
}

/// The mean of the interior of a lit view.
fn interior_mean(path: &Path) -> f64 {
    let (w, h, lit) = gray(path);
    let inner: Vec<f64> = (1..h - 1)
        .flat_map(|y| (1..w - 1).map(move |x| (x, y)))
        .map(|(x, y)| f64::from(lit[(y * w + x) as usize]))
        .collect();
    inner.iter().sum::<f64>() / inner.len() as f64
}

#[test]
fn the_light_direction_picks_the_faces_it_brightens() {
    let dir = tempfile::tempdir().unwrap();
    // Rising to the right: the slope faces left. Rising down the image: it faces up.
    let (east, south) = (dir.path().join("east.png"), dir.path().join("south.png"));
    write_gray16(&east, 32, 24, |x, _| 4000 + 1500 * x as u16);
    write_gray16(&south, 32, 24, |_, y| 4000 + 2000 * y as u16);
    let lit = |input: &Path, light: &str, extra: &[&str]| {
        let out = dir.path().join(format!("lit_{}_{light}.png", input.file_stem().unwrap().to_string_lossy()));
        let args = [&["shade", s(input), "-s", "8", "--border", "clamp", "--light", light, "-o", s(&out)][..], extra];
        ok(&run(&args.concat()));
        interior_mean(&out)
    };
    let (from_left, from_right) = (lit(&east, "180,30", &[]), lit(&east, "0,30", &[]));
    assert!(from_left > from_right + 40.0, "left {from_left}, right {from_right}");
    let (from_top, from_bottom) = (lit(&south, "90,30", &[]), lit(&south, "270,30", &[]));
    assert!(from_top > from_bottom + 40.0, "top {from_top}, bottom {from_bottom}");
    // Either convention shows the same picture: only the files' green differs.
    assert_eq!(lit(&south, "90,30", &["--convention", "dx"]), from_top);
    // A light across the slope sees it as flat ground would: the same on both sides.
    assert!((lit(&east, "90,30", &[]) - lit(&east, "270,30", &[])).abs() < 1e-9);
    // Depths instead of heights turn the slope around.
    assert!(lit(&east, "0,30", &["--invert"]) > lit(&east, "180,30", &["--invert"]) + 40.0);
}

#[test]
fn a_height_map_goes_through_the_same_fit_as_convert() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_bumpy(&input, 40, 30);
    let fit = ["-n", "5", "--fit", "vertical", "--border", "clamp,mirror", "-s", "7", "--invert", "--convention", "dx"];
    let normal_map = dir.path().join("n.png");
    ok(&run(&[&["convert", s(&input), "-o", s(&normal_map), "--bits", "16"][..], &fit].concat()));
    let (from_heights, from_normals) = (dir.path().join("a.png"), dir.path().join("b.png"));
    ok(&run(&[&["shade", s(&input), "-o", s(&from_heights)][..], &fit].concat()));
    ok(&run(&["shade", s(&normal_map), "--convention", "dx", "-o", s(&from_normals)]));
    let (a, b) = (gray(&from_heights).2, gray(&from_normals).2);
    // The normal map holds the normals rounded to 16 bits: a value may round
    // the other way, no more.
    assert!(a.iter().zip(&b).all(|(x, y)| x.abs_diff(*y) <= 1));
    assert!(a.iter().zip(&b).filter(|(x, y)| x != y).count() * 50 < a.len(), "nearly all equal");
    // And the options matter: the default fit gives another picture.
    let default = dir.path().join("default.png");
    ok(&run(&["shade", s(&input), "-o", s(&default)]));
    assert!(gray(&default).2.iter().zip(&a).filter(|(x, y)| x.abs_diff(**y) > 2).count() > a.len() / 4);
}

#[test]
fn outputs_go_beside_inputs_into_folders_or_to_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    write_bumpy(&a, 16, 12);
    write_bumpy(&b, 10, 8);
    ok(&run(&["shade", s(&a), s(&b)]));
    let beside = [dir.path().join("a_lit.png"), dir.path().join("b_lit.png")];
    assert_eq!(gray(&beside[0]).0, 16);
    assert_eq!(gray(&beside[1]).0, 10);

    let folder = dir.path().join("lit");
    ok(&run(&["shade", s(&a), s(&b), "-o", s(&folder), "--tile"]));
    assert_eq!(gray(&folder.join("a_lit.png")).0, 32);
    assert_eq!(gray(&folder.join("b_lit.png")).0, 20);

    let out = run(&["shade", s(&a), "-o", "-"]);
    ok(&out);
    let piped = image::load_from_memory(&out.stdout).unwrap().into_luma8().into_raw();
    assert_eq!(piped, gray(&beside[0]).2);
    // Standard input in, standard output out.
    let out = Command::new(env!("CARGO_BIN_EXE_normalfit"))
        .args(["shade", "-"])
        .stdin(fs::File::open(&a).unwrap())
        .output()
        .unwrap();
    ok(&out);
    assert_eq!(image::load_from_memory(&out.stdout).unwrap().into_luma8().into_raw(), piped);
}

#[test]
fn errors_are_one_line_and_the_other_inputs_are_still_written() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.png");
    write_bumpy(&good, 16, 12);
    let out = dir.path().join("out.png");

    for bad in ["abc", "135", "135,95", "x,30", "135,-5", "135,30,1", "inf,30"] {
        let line = error_line(&run(&["shade", s(&good), "--light", bad, "-o", s(&out)]));
        assert!(line.starts_with("normalfit: ") && line.contains("light"), "{bad}: {line}");
    }
    assert!(!out.exists());
    // A negative azimuth is a direction, not an option.
    ok(&run(&["shade", s(&good), "--light", "-45,30", "-o", s(&out)]));

    let missing = dir.path().join("missing.png");
    let lit_dir = dir.path().join("lit");
    let line = error_line(&run(&["shade", s(&missing), s(&good), "-o", s(&lit_dir)]));
    assert!(line.contains("missing.png"), "{line}");
    assert!(lit_dir.join("good_lit.png").exists(), "the good input is still shaded");

    let before = fs::read(&good).unwrap();
    let line = error_line(&run(&["shade", s(&good), "-o", s(&good)]));
    assert!(line.contains("good.png") && line.contains("never writes over an input"), "{line}");
    assert_eq!(fs::read(&good).unwrap(), before, "the input is untouched");

    let line = error_line(&run(&["shade", s(&good), "-o", s(&dir.path().join("lit.jpg"))]));
    assert!(line.contains("lit.jpg") && line.contains("PNG"), "{line}");
    let line = error_line(&run(&["shade", s(&good), "--kind", "normal", "-o", s(&out)]));
    assert!(line.contains("good.png") && line.contains("R, G and B"), "{line}");
    let line = error_line(&run(&["shade", s(&good), "--signed", "-o", s(&out)]));
    // The library's message names the option, not the flag.
    assert!(line.contains("good.png") && line.contains("signed is for normal maps"), "{line}");

    let rgb = dir.path().join("rgb.png");
    image::RgbImage::from_pixel(4, 4, image::Rgb([128, 128, 255])).save(&rgb).unwrap();
    let line = error_line(&run(&["shade", s(&rgb), "--signed", "-o", s(&out)]));
    assert!(line.contains("rgb.png") && line.contains("float"), "{line}");

    let line = error_line(&run(&["shade", s(&good), s(&rgb), "-o", "-"]));
    assert!(line.contains("standard output"), "{line}");
    let line = error_line(&run(&["shade", s(&good), "-n", "4"]));
    assert!(line.contains("patch"), "{line}");
}

/// The README's gallery: every picture in docs/gallery/ is exactly what the
/// README's commands make from the gallery's height maps.
#[test]
fn the_gallery_is_what_the_readme_commands_make() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let readme = fs::read_to_string(root.join("README.md")).unwrap();
    let commands: Vec<Vec<&str>> = readme
        .lines()
        .filter(|l| l.starts_with("normalfit ") && l.contains("docs/gallery/"))
        .map(|l| l.split_whitespace().skip(1).collect())
        .collect();
    assert!(commands.len() >= 9, "a normal map, a lit view and a tiled view per sample: {commands:?}");
    let dir = tempfile::tempdir().unwrap();
    let mut shown = Vec::new();
    for args in commands {
        let o = args.iter().position(|a| *a == "-o").expect("gallery commands name their output");
        let shipped = root.join(args[o + 1]);
        let made = dir.path().join(shipped.file_name().unwrap());
        let mut args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        args[o + 1] = s(&made).to_string();
        let out = Command::new(env!("CARGO_BIN_EXE_normalfit")).current_dir(&root).args(&args).output().unwrap();
        ok(&out);
        let (made_img, shipped_img) = (image::open(&made).unwrap(), image::open(&shipped).unwrap());
        assert_eq!(made_img.color(), shipped_img.color(), "{}", shipped.display());
        assert_eq!(made_img.as_bytes(), shipped_img.as_bytes(), "{} is not what {args:?} makes", shipped.display());
        assert!(readme.contains(&format!("({})", shipped.strip_prefix(&root).unwrap().display())), "shown");
        shown.push(shipped);
    }
    for sample in ["bricks", "rock", "terrain"] {
        for suffix in ["_normal", "_lit", "_tiled"] {
            let picture = root.join(format!("docs/gallery/{sample}{suffix}.png"));
            assert!(shown.contains(&picture), "{} is made by a README command", picture.display());
        }
    }
}

#[test]
fn the_sun_lights_with_azimuth_and_altitude_and_refuses_a_light_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ramp.png");
    // Rising to the east, the slope faces west: a sun in the west (270°)
    // lights it more than flat ground, 1 + 254 · sin 45° = 181, one in the
    // east (90°) less (no georeferencing: north is up the image).
    write_gray16(&input, 16, 16, |x, _| (x * 2000) as u16);
    let grey = |azimuth: &str| {
        let out = dir.path().join(format!("lit{azimuth}.png"));
        ok(&run(&["shade", s(&input), "-o", s(&out), "--border", "clamp", "--azimuth", azimuth]));
        let (_, _, v) = gray(&out);
        v[8 * 16 + 8]
    };
    let (west, east) = (grey("270"), grey("90"));
    assert!(west > 181 && east < 181, "west {west}, east {east}");
    let e = error_line(&run(&["shade", s(&input), "--light", "135,35", "--azimuth", "315"]));
    assert!(e.contains("--azimuth") || e.contains("--light"), "{e}");
    let e = error_line(&run(&["shade", s(&input), "--altitude", "95"]));
    assert!(e.contains("altitude"), "{e}");
}
