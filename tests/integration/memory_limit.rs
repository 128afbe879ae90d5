//! One memory rule for every path (issue 32): under a 1 GiB address-space
//! limit (`ulimit -v`), every path that allocates what grows with N (the
//! whole-image fit, the streamed one, the masked fit, the lit view, the
//! inverse) either runs or is refused before it allocates, in one line
//! naming the file (exit 2, no output, no temporary file), never with an
//! abort ("memory allocation of … failed", SIGABRT), whatever the shape
//! and N. Each run is a child process under the limit.
//!
//! The children run on 2 threads (`RAYON_NUM_THREADS`): the rule counts
//! each thread of the pool (its allocator's heap, its stack), so the cases
//! that must run or must be refused are the same on any machine.

use crate::common;

use std::fs;
use std::io::BufWriter;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::cli::{is_summary, listing, run, s};

const GIB: u64 = 1 << 30;

/// Runs the binary with `args` under an address-space limit of `bytes`
/// (`ulimit -v` in sh), reading `stdin` (else nothing), on 2 threads.
fn limited(bytes: u64, args: &[&str], stdin: Option<&Path>) -> Output {
    let mut command = Command::new("sh");
    command
        .args(["-c", &format!("ulimit -v {} && exec \"$0\" \"$@\"", bytes / 1024), env!("CARGO_BIN_EXE_normalfit")])
        .args(args)
        .env("RAYON_NUM_THREADS", "2")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    match stdin {
        Some(path) => command.stdin(fs::File::open(path).unwrap()),
        None => command.stdin(Stdio::null()),
    };
    command.output().unwrap()
}

/// A 16-bit gray PNG of `w` × `h` texels: a slope with a ripple.
fn write_gray16(path: &Path, w: u32, h: u32) {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        let v = 0.4 * (x as f64 / w as f64) + 0.2 * (y as f64 / h as f64) + 0.1 * (x as f64 * 0.05).sin();
        image::Luma([(v.clamp(0.0, 1.0) * 65535.0).round() as u16])
    });
    let file = BufWriter::new(fs::File::create(path).unwrap());
    img.write_with_encoder(image::codecs::png::PngEncoder::new(file)).unwrap();
}

/// A 16-bit GeoTIFF of `w` × `h` texels (30 m UTM pixels), which is
/// read whole.
fn write_geotiff16(path: &Path, w: usize, h: usize) {
    use common::geotiff::{self, Kind, Layout};
    let layout = Layout::gray(Kind::U16);
    let values = geotiff::band_values(&layout, w, h);
    fs::write(path, geotiff::write(w, h, &layout, &values, &geotiff::utm_tags())).unwrap();
}

/// The inputs of one shape: a height map (PNG and GeoTIFF).
struct Inputs {
    png: PathBuf,
    tif: PathBuf,
}

impl Inputs {
    /// The normal map of the heights fitted at `n`, for `height -n n`: the
    /// inverse of the fit's own map settles in a few solves, as the memory
    /// it holds does not depend on the map. (A map made at another N is
    /// one the orthogonal inverse cannot settle on: hundreds of solves,
    /// 17 s for these 60 000 texels at N = 63, which measure nothing more
    /// here.)
    fn normals(&self, n: &str) -> PathBuf {
        let normals = self.png.with_file_name(format!("n{n}_{}", self.png.file_name().unwrap().to_str().unwrap()));
        if !normals.exists() {
            let r = run(&["convert", s(&self.png), "-o", s(&normals), "--bits", "16", "-n", n]);
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        }
        normals
    }
}

fn inputs(dir: &Path, (w, h): (u32, u32)) -> Inputs {
    let png = dir.join(format!("h{w}x{h}.png"));
    write_gray16(&png, w, h);
    let tif = dir.join(format!("h{w}x{h}.tif"));
    write_geotiff16(&tif, w as usize, h as usize);
    Inputs { png, tif }
}

/// What a run under the limit did.
#[derive(Debug, PartialEq)]
enum Outcome {
    Ran,
    Refused(String),
}

/// Runs one path under the limit and checks that it ran (its output
/// there) or was refused cleanly: exit 2, not a signal, one line naming
/// `subject` and saying memory is short, no output and no temporary file
/// in `out`'s folder.
fn check(limit: u64, what: &str, args: &[&str], stdin: Option<&Path>, subject: &Path, out: &Path) -> Outcome {
    let folder = out.parent().unwrap();
    let r = limited(limit, args, stdin);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.signal().is_none(), "{what}: killed by a signal: {:?}: {stderr}", r.status);
    assert!(!stderr.contains("memory allocation") && !stderr.contains("panicked"), "{what}: {stderr}");
    let outcome = if r.status.success() {
        assert!(out.exists(), "{what}: ran, but wrote no {}", out.display());
        Outcome::Ran
    } else {
        assert_eq!(r.status.code(), Some(2), "{what}: {stderr}");
        let errors: Vec<&str> =
            stderr.lines().filter(|l| !l.starts_with("normalfit: warning: ") && !is_summary(l)).collect();
        assert_eq!(errors.len(), 1, "{what}: want one line, got {stderr:?}");
        let line = errors[0];
        assert!(line.starts_with(&format!("normalfit: {}: too large: ", subject.display())), "{what}: {line}");
        let limit_said = format!("(its memory limit is {} MiB)", limit >> 20);
        assert!(line.contains("memory") && line.ends_with(&limit_said), "{what}: {line}");
        assert_eq!(listing(folder), Vec::<String>::new(), "{what}: no output, no temporary file after a refusal");
        Outcome::Refused(line.to_string())
    };
    fs::remove_dir_all(folder).unwrap();
    fs::create_dir(folder).unwrap();
    outcome
}

/// Every path under 1 GiB, for a 20000 × 3 and a 3 × 20000 image, N =
/// 1023 and 255: runs or is refused in one line. A float fit of the wide
/// image at N = 1023 needs some 2 GiB of sums (a strip of 8·N columns holds
/// 2N rows of them, on each thread): the whole-image conversion, the lit
/// view, the masked fit and the streamed float fit are refused; at N = 255
/// every path runs.
#[test]
#[cfg_attr(not(target_os = "linux"), ignore = "the memory rule reads the process's use in /proc (Linux)")]
fn every_path_runs_or_is_refused_in_one_line_under_1_gib() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("out");
    fs::create_dir(&folder).unwrap();
    let (o, r, exr) = (folder.join("o.png"), folder.join("r.png"), folder.join("h.exr"));
    let stdin = Path::new("<standard input>");
    let mut refused = Vec::new();
    for (w, h) in [(20000u32, 3u32), (3, 20000)] {
        let i = inputs(dir.path(), (w, h));
        for n in ["1023", "255"] {
            let normals = i.normals(n);
            // (what, arguments, standard input, the file named)
            let cases: Vec<(&str, Vec<&str>, Option<&Path>, &Path)> = vec![
                ("streamed", vec!["convert", s(&i.png), "-o", s(&o), "-n", n], None, &i.png),
                (
                    "streamed, floats",
                    vec!["convert", s(&i.png), "-o", s(&o), "-n", n, "--pixel-size", "1"],
                    None,
                    &i.png,
                ),
                ("streamed, holes", vec!["convert", s(&i.png), "-o", s(&o), "-n", n, "--nodata", "0"], None, &i.png),
                ("whole", vec!["convert", "-", "-o", s(&o), "-n", n], Some(&i.png), stdin),
                ("whole, floats", vec!["convert", "-", "-o", s(&o), "-n", n, "--pixel-size", "1"], Some(&i.png), stdin),
                ("whole, map units", vec!["convert", s(&i.tif), "-o", s(&o), "-n", n, "--units", "map"], None, &i.tif),
                (
                    "whole, holes",
                    vec!["convert", "-", "-o", s(&o), "-n", n, "--nodata", "0", "--residual", s(&r)],
                    Some(&i.png),
                    stdin,
                ),
                ("shade", vec!["shade", s(&i.png), "-o", s(&o), "-n", n], None, &i.png),
                ("shade, map units", vec!["shade", s(&i.tif), "-o", s(&o), "-n", n, "--units", "map"], None, &i.tif),
                ("height", vec!["height", s(&normals), "-o", s(&exr), "-n", n], None, &normals),
            ];
            for (what, args, input, subject) in cases {
                let what = format!("{what}, {w}×{h}, N = {n}");
                let out = if args[0] == "height" { &exr } else { &o };
                match check(GIB, &what, &args, input, subject, out) {
                    Outcome::Ran => println!("{what}: ran"),
                    Outcome::Refused(line) => {
                        println!("{what}: {line}");
                        refused.push(what);
                    }
                }
            }
        }
    }
    for must in ["whole, floats", "whole, map units", "shade", "shade, map units", "streamed, floats"] {
        let what = format!("{must}, 20000×3, N = 1023");
        assert!(refused.contains(&what), "{what} needs about 2 GiB, yet it was not refused: {refused:?}");
    }
    assert!(refused.iter().all(|r| r.ends_with("N = 1023")), "at N = 255 every path runs: {refused:?}");
}

/// The rule does not refuse what fits: N = 31 runs on every path under
/// 1 GiB, and the outputs are those of a run without a limit.
#[test]
#[cfg_attr(not(target_os = "linux"), ignore = "the memory rule reads the process's use in /proc (Linux)")]
fn a_moderate_patch_runs_on_every_path_under_1_gib() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("out");
    fs::create_dir(&folder).unwrap();
    for (w, h) in [(20000u32, 3u32), (3, 20000)] {
        let i = inputs(dir.path(), (w, h));
        let normals = i.normals("31");
        for (what, args) in [
            ("whole, map units", vec!["convert", s(&i.tif), "--units", "map", "-n", "31", "--nodata", "0"]),
            ("shade", vec!["shade", s(&i.png), "-n", "31"]),
            ("height", vec!["height", s(&normals), "-n", "31"]),
        ] {
            let ext = if what == "height" { "exr" } else { "png" };
            let (limited_out, free_out) = (folder.join(format!("a.{ext}")), dir.path().join(format!("b.{ext}")));
            let mut args = args.clone();
            args.extend(["-o", s(&limited_out)]);
            let r = limited(GIB, &args, None);
            assert!(r.status.success(), "{what}, {w}×{h}: {}", String::from_utf8_lossy(&r.stderr));
            *args.last_mut().unwrap() = s(&free_out);
            let r = run(&args);
            assert!(r.status.success(), "{what}, {w}×{h}: {}", String::from_utf8_lossy(&r.stderr));
            assert!(fs::read(&limited_out).unwrap() == fs::read(&free_out).unwrap(), "{what}, {w}×{h}: the same bytes");
            fs::remove_file(&limited_out).unwrap();
            fs::remove_file(&free_out).unwrap();
        }
    }
}

/// The estimates hold from too little to enough: paths whose work grows
/// with N, at limits from 200 MiB to 1000 MiB in steps of 100, each run or
/// refused in one line, never an abort; refused at the first step, run at
/// the last.
#[test]
#[cfg_attr(not(target_os = "linux"), ignore = "the memory rule reads the process's use in /proc (Linux)")]
fn tightening_limits_never_abort_a_path_that_grows_with_n() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("out");
    fs::create_dir(&folder).unwrap();
    let i = inputs(dir.path(), (20000, 3));
    let (o, exr) = (folder.join("o.png"), folder.join("h.exr"));
    let normals = i.normals("63");
    for (what, args, out) in [
        ("shade", vec!["shade", s(&i.png), "-o", s(&o), "-n", "255"], &o),
        ("streamed, floats", vec!["convert", s(&i.png), "-o", s(&o), "-n", "255", "--pixel-size", "1"], &o),
        // The inverse's wrapped solve (clamp's dense bases have a test of their own below).
        ("height", vec!["height", s(&normals), "-o", s(&exr), "-n", "63"], &exr),
    ] {
        let subject = Path::new(args[1]);
        let outcomes: Vec<(u64, Outcome)> = (2..=10)
            .map(|k| {
                let mib = 100 * k;
                (mib, check(mib << 20, &format!("{what} at {mib} MiB"), &args, None, subject, out))
            })
            .collect();
        let ran: Vec<u64> = outcomes.iter().filter(|(_, o)| *o == Outcome::Ran).map(|(m, _)| *m).collect();
        println!("{what}: ran at {ran:?} MiB");
        assert_ne!(outcomes[0].1, Outcome::Ran, "{what}: 200 MiB is too little, yet it ran");
        assert_eq!(outcomes.last().unwrap().1, Outcome::Ran, "{what}: refused at 1000 MiB");
    }
}

/// The inverse where no transform fits (clamp borders, N ≥ 5) solves in
/// dense bases (`height/dense.rs`: per axis several n × n matrices while
/// they are made, and the null modes' projection), a cost the shape sets,
/// not N's line sums: on a 600 × 3 map at N = 255, limits from 200 MiB to
/// 1000 MiB in steps of 100 each run or refuse in one line, never an
/// abort; refused at the first step, run at the last.
#[test]
#[cfg_attr(not(target_os = "linux"), ignore = "the memory rule reads the process's use in /proc (Linux)")]
fn tightening_limits_never_abort_the_inverse_in_dense_bases() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("out");
    fs::create_dir(&folder).unwrap();
    let (png, normals) = (dir.path().join("h600x3.png"), dir.path().join("n600x3.png"));
    write_gray16(&png, 600, 3);
    let r = run(&["convert", s(&png), "-o", s(&normals), "--bits", "16", "-n", "255", "--border", "clamp"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let exr = folder.join("h.exr");
    let args = ["height", s(&normals), "-o", s(&exr), "-n", "255", "--border", "clamp"];
    let outcomes: Vec<(u64, Outcome)> = (2..=10)
        .map(|k| {
            let mib = 100 * k;
            (mib, check(mib << 20, &format!("height, clamp, at {mib} MiB"), &args, None, &normals, &exr))
        })
        .collect();
    let ran: Vec<u64> = outcomes.iter().filter(|(_, o)| *o == Outcome::Ran).map(|(m, _)| *m).collect();
    println!("height, clamp: ran at {ran:?} MiB");
    assert_ne!(outcomes[0].1, Outcome::Ran, "200 MiB is too little, yet it ran");
    assert_eq!(outcomes.last().unwrap().1, Outcome::Ran, "refused at 1000 MiB");
}

/// Many files at once under a limit: a batch starts threads for its jobs,
/// each file's stages and exr's block decoders, and glibc would give each
/// a heap that reserves 64 MiB of address space. Eight small files of
/// three formats, four at a time (`-j 4`), under 512 MiB, all convert; and
/// the default under a limit (one at a time) gives the same files.
#[test]
#[cfg_attr(not(target_os = "linux"), ignore = "the memory rule reads the process's use in /proc (Linux)")]
fn a_batch_of_small_files_converts_whole_under_a_limit() {
    let dir = tempfile::tempdir().unwrap();
    let mut names = Vec::new();
    for k in 0..4u32 {
        let png = dir.path().join(format!("p{k}.png"));
        write_gray16(&png, 24 + k, 16);
        let exr = dir.path().join(format!("e{k}.exr"));
        let r = run(&["convert", s(&png), "-o", s(&exr)]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        names.extend([png, exr]);
    }
    let inputs: Vec<&str> = names.iter().map(|p| s(p)).collect();
    for (jobs, folder) in [(Some("4"), "four"), (None, "default")] {
        let out = dir.path().join(folder);
        let mut args = vec!["convert"];
        args.extend(&inputs);
        args.extend(["--border", "clamp", "-o", s(&out)]);
        if let Some(jobs) = jobs {
            args.extend(["-j", jobs]);
        }
        let r = limited(512 << 20, &args, None);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{folder}: {stderr}");
        assert_eq!(stderr.lines().filter(|l| !is_summary(l)).count(), 0, "{folder}: {stderr}");
        assert_eq!(listing(&out).len(), 8, "{folder}: {:?}", listing(&out));
    }
    for name in listing(&dir.path().join("four")) {
        let (a, b) = (dir.path().join("four").join(&name), dir.path().join("default").join(&name));
        assert!(fs::read(a).unwrap() == fs::read(b).unwrap(), "{name}: the same bytes at once or one at a time");
    }
}
