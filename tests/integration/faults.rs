//! Faults while writing, and memory limits: whatever goes wrong, a clear
//! one-line error (exit 2), the target keeps its old content or stays
//! absent, no temporary file is left, and the inputs are untouched. Every
//! run of the binary here is under a 1 GiB address-space limit.
//!
//! Some faults need root (a tmpfs small enough to fill): that test is
//! ignored by a plain `cargo test` and run by `cargo test --
//! --include-ignored` (the README's and CI's command; CI runs as root),
//! where a missing privilege fails it instead of passing it unseen. A
//! read-only folder is a read-only tmpfs as root and a mode-0555 folder
//! otherwise, so that test always runs.

use crate::common;

use std::fs;
use std::io::{BufWriter, Write};
use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::cli::{bin_within, is_summary, listing, run_within, s};

/// Every run of this suite is under a 1 GiB address-space limit (issue
/// 32): faults are errors in one line there too, never an abort.
fn bin() -> Command {
    bin_within(GIB)
}

fn run(args: &[&str]) -> Output {
    run_within(GIB, args)
}

/// A 16-bit gray height map, a slope with a bump and some noise, so its
/// normal map compresses poorly and takes a while to write.
fn write_gray16(path: &Path, w: u32, h: u32) {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        let (dx, dy) = (x as f64 - w as f64 / 2.0, y as f64 - h as f64 / 3.0);
        let noise = ((x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)) % 1000) as f64 / 1000.0;
        let v = 0.3 * x as f64 / w as f64 + 0.5 * (-(dx * dx + dy * dy) / 4000.0).exp() + 0.05 * noise;
        image::Luma([(v.min(1.0) * 65535.0).round() as u16])
    });
    let file = BufWriter::new(fs::File::create(path).unwrap());
    let encoder = image::codecs::png::PngEncoder::new_with_quality(
        file,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    );
    img.write_with_encoder(encoder).unwrap();
}

fn write_gray8(path: &Path, w: u32, h: u32) {
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([((x * 37 + y * 11) % 256) as u8])).save(path).unwrap();
}

/// Files whose bytes must come out of a run as they went in.
struct Untouched(Vec<(PathBuf, Vec<u8>)>);

impl Untouched {
    fn of(paths: &[&Path]) -> Untouched {
        Untouched(paths.iter().map(|p| (p.to_path_buf(), fs::read(p).unwrap())).collect())
    }

    fn check(&self, when: &str) {
        for (path, bytes) in &self.0 {
            assert!(fs::read(path).unwrap() == *bytes, "{when}: {} changed", path.display());
        }
    }
}

/// Checks a failed run: exit code 2 (not a signal), one error line on
/// standard error that starts `normalfit: <subject>: ` and says one of
/// `problem` (lower case). Returns the line.
fn expect_fault(out: &Output, subject: &Path, problem: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "exit status {:?}, stderr {stderr:?}", out.status);
    assert!(!stderr.contains("panicked") && !stderr.contains("backtrace"), "{stderr}");
    let errors: Vec<&str> =
        stderr.lines().filter(|l| !l.starts_with("normalfit: warning: ") && !is_summary(l)).collect();
    assert_eq!(errors.len(), 1, "want one error line, got {stderr:?}");
    let line = errors[0].to_string();
    assert!(line.starts_with(&format!("normalfit: {}: ", subject.display())), "names {}: {line}", subject.display());
    let lower = line.to_lowercase();
    assert!(problem.iter().any(|p| lower.contains(p)), "says one of {problem:?}: {line}");
    line
}

fn is_root() -> bool {
    rustix::process::geteuid().is_root()
}

/// A file system mounted for one test, unmounted when dropped (also when
/// the test fails).
struct Mount(PathBuf);

impl Mount {
    /// Mounts a tmpfs with `options` on `dir` (made if missing).
    fn tmpfs(dir: &Path, options: &str) -> Result<Mount, String> {
        fs::create_dir_all(dir).unwrap();
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs", s(dir)])
            .output()
            .map_err(|e| format!("cannot run mount: {e}"))?;
        if !out.status.success() {
            return Err(format!("mount -t tmpfs failed: {}", String::from_utf8_lossy(&out.stderr).trim()));
        }
        Ok(Mount(dir.to_path_buf()))
    }

    /// Makes it read-only.
    fn remount_read_only(&self) -> Result<(), String> {
        let out = Command::new("mount").args(["-o", "remount,ro", s(&self.0)]).output().map_err(|e| e.to_string())?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!("remount read-only failed: {}", String::from_utf8_lossy(&out.stderr).trim()))
        }
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        let ok = Command::new("umount").arg(&self.0).status().is_ok_and(|s| s.success());
        if !ok {
            // Busy (a child still running after a failed assertion): detach it.
            let _ = Command::new("umount").arg("-l").arg(&self.0).status();
        }
    }
}

/// A folder whose files cannot be created: a read-only tmpfs as root (root
/// ignores permission bits), mode 0555 otherwise. `setup` runs on it while
/// it is still writable. `None` (with the reason) when neither works.
enum ReadOnly {
    Mounted(#[allow(dead_code)] Mount),
    Chmod(PathBuf),
}

impl ReadOnly {
    fn make(dir: &Path, setup: impl FnOnce(&Path)) -> Result<ReadOnly, String> {
        if is_root() {
            let mount = Mount::tmpfs(dir, "size=1m")?;
            setup(dir);
            mount.remount_read_only()?;
            Ok(ReadOnly::Mounted(mount))
        } else {
            fs::create_dir_all(dir).unwrap();
            setup(dir);
            fs::set_permissions(dir, fs::Permissions::from_mode(0o555)).unwrap();
            Ok(ReadOnly::Chmod(dir.to_path_buf()))
        }
    }
}

impl Drop for ReadOnly {
    fn drop(&mut self) {
        if let ReadOnly::Chmod(dir) = self {
            // So the temporary folder can be removed.
            let _ = fs::set_permissions(dir, fs::Permissions::from_mode(0o755));
        }
    }
}

#[test]
fn a_missing_output_folder_is_an_error_for_a_file_and_made_for_a_folder() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    write_gray8(&a, 9, 7);
    write_gray16(&b, 12, 5);
    let inputs = Untouched::of(&[&a, &b]);

    // One input, a file path whose folder does not exist: an error that
    // names the file and the missing folder; no folder is made.
    for name in ["o.png", "o.exr"] {
        let target = dir.path().join("nope").join(name);
        let line = expect_fault(&run(&["convert", s(&a), "-o", s(&target)]), &target, &["does not exist"]);
        assert!(line.contains(&format!("the folder {} does not exist", s(&dir.path().join("nope")))), "{line}");
        assert_eq!(listing(dir.path()), ["a.png", "b.png"]);
    }
    inputs.check("missing folder");

    // Many inputs: -o names a folder, made if missing (with its parents).
    let outdir = dir.path().join("new").join("normals");
    let r = run(&["convert", s(&a), s(&b), "-o", s(&outdir)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(listing(&outdir), ["a_normal.png", "b_normal.png"]);

    // One input and a trailing slash: a folder too, made if missing.
    let slash = format!("{}/", s(&dir.path().join("one")));
    let r = run(&["convert", s(&a), "-o", &slash]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(listing(&dir.path().join("one")), ["a_normal.png"]);
    inputs.check("folders made");
}

#[test]
fn a_read_only_output_folder_is_an_error_that_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray16(&input, 64, 48);
    let inputs = Untouched::of(&[&input]);
    let ro = dir.path().join("ro");
    let folder = match ReadOnly::make(&ro, |d| {
        fs::write(d.join("o.png"), b"old png").unwrap();
        fs::write(d.join("o.exr"), b"old exr").unwrap();
    }) {
        Ok(f) => f,
        Err(why) => panic!("no read-only folder to write into: {why}"),
    };
    // A streamed PNG and a whole-image EXR take the same way to the file.
    for (name, old) in [("o.png", &b"old png"[..]), ("o.exr", b"old exr")] {
        let target = ro.join(name);
        let line = expect_fault(&run(&["convert", s(&input), "-o", s(&target)]), &target, &["read-only", "permission"]);
        assert!(line.contains("cannot create a file in the folder"), "{line}");
        assert_eq!(fs::read(&target).unwrap(), old, "{name}");
        assert_eq!(listing(&ro), ["o.exr", "o.png"], "{name}");
    }
    inputs.check("read-only folder");
    drop(folder);
}

#[test]
#[ignore = "needs root to mount a small tmpfs; CI runs as root with --include-ignored"]
fn a_full_disk_is_an_error_that_leaves_the_old_output_and_nothing_else() {
    assert!(is_root(), "needs root to mount a small tmpfs");
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    // 512², and a strong gain so the noise shows in the normals.
    write_gray16(&input, 512, 512);
    let inputs = Untouched::of(&[&input]);
    let small = dir.path().join("small");
    let mount = Mount::tmpfs(&small, "size=256k").unwrap_or_else(|why| panic!("no small file system to fill: {why}"));
    for (name, extra) in [("o.png", &["--bits", "16"][..]), ("o.exr", &[]), ("o8.png", &["--bits", "8"])] {
        let mut args = vec!["convert", s(&input), "--scale", "200"];
        args.extend_from_slice(extra);
        // Where there is room, the output is more than twice the tmpfs.
        let roomy = dir.path().join(name);
        let r = run(&[&args[..], &["-o", s(&roomy)]].concat());
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let size = fs::metadata(&roomy).unwrap().len();
        assert!(size > 512 << 10, "{name}: {size} bytes would fit");
        fs::remove_file(&roomy).unwrap();

        let target = small.join(name);
        fs::write(&target, b"old").unwrap();
        let r = run(&[&args[..], &["-o", s(&target)]].concat());
        expect_fault(&r, &target, &["no space"]);
        if name.ends_with(".png") {
            // The input does not tile in x, but the streamed check saw only
            // the rows before the failure: no warning from half an image.
            assert_eq!(String::from_utf8_lossy(&r.stderr).lines().count(), 1, "{name}");
        }
        assert_eq!(fs::read(&target).unwrap(), b"old", "{name}");
        assert_eq!(listing(&small), [name], "{name}");
        fs::remove_file(&target).unwrap();
    }
    // shade: the lit view streamed, whole (tiled) and of a normal map, and
    // into a GeoTIFF; the line names the output it could not write, never
    // the input (issue 32).
    let lit_input = dir.path().join("hs.png");
    write_gray16(&lit_input, 1024, 1024);
    let normal_map = dir.path().join("nm.png");
    let r = run(&["convert", s(&lit_input), "--scale", "200", "-o", s(&normal_map)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let inputs_too = Untouched::of(&[&lit_input, &normal_map]);
    for (name, from, extra) in [
        ("lit.png", &lit_input, &["--scale", "200"][..]),
        ("lit_tiled.png", &lit_input, &["--scale", "200", "--tile"]),
        ("lit.tif", &lit_input, &["--scale", "200"]),
        ("lit_normals.png", &normal_map, &[]),
    ] {
        let target = small.join(name);
        fs::write(&target, b"old").unwrap();
        let r = run(&[&["shade", s(from), "-o", s(&target)], extra].concat());
        expect_fault(&r, &target, &["no space"]);
        assert_eq!(fs::read(&target).unwrap(), b"old", "{name}");
        assert_eq!(listing(&small), [name], "{name}");
        fs::remove_file(&target).unwrap();
    }
    inputs_too.check("shade onto a full disk");

    // No target before: none after.
    let target = small.join("fresh.png");
    let r = run(&["convert", s(&input), "-o", s(&target), "--bits", "16", "--scale", "200"]);
    expect_fault(&r, &target, &["no space"]);
    assert!(listing(&small).is_empty());

    // The library call says the same, with the kind of error intact.
    let e = normalfit::io::write_atomically(&small.join("lib.bin"), |out| {
        for _ in 0..64 {
            out.write_all(&[0x5a; 16 << 10])?;
        }
        Ok(())
    })
    .unwrap_err();
    assert!(matches!(&e, normalfit::Error::Io(io) if io.kind() == std::io::ErrorKind::StorageFull), "{e:?}");
    assert!(listing(&small).is_empty());
    inputs.check("full disk");
    drop(mount);
}

#[test]
fn an_output_that_is_an_input_or_a_link_to_one_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 8, 8);
    let hard = dir.path().join("hard.png");
    fs::hard_link(&input, &hard).unwrap();
    let soft = dir.path().join("soft.png");
    std::os::unix::fs::symlink(&input, &soft).unwrap();
    let inode = fs::metadata(&input).unwrap().ino();
    let inputs = Untouched::of(&[&input]);
    let before = listing(dir.path());
    let spelled_otherwise = dir.path().join(".").join("h.png");
    for target in [&input, &hard, &soft, &spelled_otherwise] {
        expect_fault(&run(&["convert", s(&input), "-o", s(target)]), target, &["is one of the inputs"]);
        // The same refusal whatever the output format.
        let r = run(&["convert", s(&input), "-o", s(target), "--format", "png", "--bits", "16"]);
        expect_fault(&r, target, &["is one of the inputs"]);
        inputs.check(&format!("output {}", target.display()));
        assert_eq!(listing(dir.path()), before, "no temporary file");
    }
    assert_eq!(fs::metadata(&hard).unwrap().ino(), inode, "the hard link still is the input");
    assert_eq!(fs::read_link(&soft).unwrap(), input, "the symbolic link is left as it was");
}

#[test]
fn an_output_path_that_is_a_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 8, 8);
    let inputs = Untouched::of(&[&input]);
    // The default output's name is taken by a folder with a file in it.
    let folder = dir.path().join("h_normal.png");
    fs::create_dir(&folder).unwrap();
    fs::write(folder.join("keep.txt"), b"mine").unwrap();
    expect_fault(&run(&["convert", s(&input)]), &folder, &["is a folder"]);
    assert_eq!(listing(&folder), ["keep.txt"]);
    assert_eq!(fs::read(folder.join("keep.txt")).unwrap(), b"mine");
    assert_eq!(listing(dir.path()), ["h.png", "h_normal.png"]);

    // Many inputs need a folder: an existing file named by -o is refused,
    // and left as it was.
    let file = dir.path().join("out");
    fs::write(&file, b"a file").unwrap();
    let other = dir.path().join("g.png");
    write_gray8(&other, 6, 6);
    expect_fault(&run(&["convert", s(&input), s(&other), "-o", s(&file)]), &file, &["is not a folder"]);
    assert_eq!(fs::read(&file).unwrap(), b"a file");
    assert_eq!(listing(dir.path()), ["g.png", "h.png", "h_normal.png", "out"]);
    inputs.check("folder in the way");
}

#[test]
fn a_batch_with_one_failing_output_still_writes_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let names = ["a", "b", "c", "d"];
    let inputs: Vec<PathBuf> = names.iter().map(|n| dir.path().join(format!("{n}.png"))).collect();
    for p in &inputs {
        write_gray16(p, 40, 30);
    }
    let untouched = Untouched::of(&inputs.iter().map(PathBuf::as_path).collect::<Vec<_>>());
    let outdir = dir.path().join("out");
    fs::create_dir(&outdir).unwrap();
    // b's output is blocked by a folder.
    let blocked = outdir.join("b_normal.png");
    fs::create_dir(&blocked).unwrap();
    let mut args = vec!["convert"];
    args.extend(inputs.iter().map(|p| s(p)));
    args.extend(["-o", s(&outdir)]);
    let r = run(&args);
    expect_fault(&r, &blocked, &["is a folder"]);
    let summary = String::from_utf8_lossy(&r.stderr).lines().find(|l| is_summary(l)).map(str::to_string);
    assert!(
        summary.as_deref().is_some_and(|l| l.starts_with("normalfit: 3 converted, 0 skipped, 1 failed")),
        "{summary:?}"
    );
    assert_eq!(listing(&outdir), ["a_normal.png", "b_normal.png", "c_normal.png", "d_normal.png"]);
    assert!(blocked.is_dir() && listing(&blocked).is_empty());
    for n in ["a", "c", "d"] {
        let got = image::open(outdir.join(format!("{n}_normal.png"))).unwrap();
        assert_eq!((got.width(), got.height()), (40, 30), "{n}");
    }
    untouched.check("batch");
}

/// Whether new files in `dir` can be kept unnamed (O_TMPFILE, Linux),
/// which is what lets a killed process leave nothing behind.
#[cfg(target_os = "linux")]
fn unnamed_files_in(dir: &Path) -> bool {
    use rustix::fs::{CWD, Mode, OFlags, openat};
    openat(CWD, dir, OFlags::WRONLY | OFlags::TMPFILE | OFlags::CLOEXEC, Mode::from_raw_mode(0o600)).is_ok()
}

#[cfg(not(target_os = "linux"))]
fn unnamed_files_in(_dir: &Path) -> bool {
    false
}

/// The size of the file process `pid` has open in `folder`, if any.
fn open_file_in(pid: u32, folder: &Path) -> Option<u64> {
    let fds = fs::read_dir(format!("/proc/{pid}/fd")).ok()?;
    fds.filter_map(Result::ok).find_map(|fd| {
        let target = fs::read_link(fd.path()).ok()?;
        target.starts_with(folder).then(|| fs::metadata(fd.path()).ok().map(|m| m.len())).flatten()
    })
}

#[test]
fn a_conversion_killed_mid_write_leaves_the_old_output_and_nothing_else() {
    use rustix::process::{Pid, Signal, kill_process};
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("big.png");
    write_gray16(&input, 4096, 4096);
    let inputs = Untouched::of(&[&input]);
    let outdir = fs::canonicalize(dir.path()).unwrap().join("out");
    fs::create_dir(&outdir).unwrap();
    // Without unnamed files a killed process leaves its temporary file:
    // the promise cannot hold there, and that is a failure, not a skip.
    assert!(
        unnamed_files_in(&outdir),
        "no O_TMPFILE in {}, where a killed process leaves its temporary file",
        s(&outdir)
    );
    let target = outdir.join("n.png");
    let args = ["convert", s(&input), "-o", s(&target), "--bits", "16"];
    // A whole run first: what a finished output weighs.
    let r = run(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let full = fs::metadata(&target).unwrap().len();
    assert!(full > 8 << 20, "the output ({full} bytes) takes a while to write");

    for signal in [Signal::KILL, Signal::TERM, Signal::INT, Signal::HUP] {
        if ignored_signals() & (1 << (signal.as_raw() - 1)) != 0 {
            // An ignored signal is inherited as ignored (nohup ignores HUP):
            // it could not end the child, so there is nothing to test.
            println!("SKIPPED {signal:?}: this test process ignores it, and so would the conversion");
            continue;
        }
        fs::write(&target, b"old").unwrap();
        let mut child = bin().args(args).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        // Killed once an eighth of the output is written: well inside the
        // write, which streams from the first rows to the last.
        let start = Instant::now();
        let written = loop {
            if let Some(len) = open_file_in(child.id(), &outdir).filter(|&len| len >= full / 8) {
                break len;
            }
            if let Some(status) = child.try_wait().unwrap() {
                panic!("{signal:?}: the conversion ended ({status}) before it was seen writing");
            }
            assert!(start.elapsed() < Duration::from_secs(120), "{signal:?}: no write seen");
            std::thread::sleep(Duration::from_millis(1));
        };
        let pid = Pid::from_raw(child.id() as i32).unwrap();
        kill_process(pid, signal).unwrap();
        let status = child.wait().unwrap();
        assert_eq!(status.signal(), Some(signal.as_raw()), "{signal:?} ended it, at {written} of {full} bytes");
        assert_eq!(fs::read(&target).unwrap(), b"old", "{signal:?}");
        assert_eq!(listing(&outdir), ["n.png"], "{signal:?}: no temporary file left");
    }
    inputs.check("killed");
}

/// The signals this process ignores (the SigIgn mask of /proc/self/status;
/// bit n − 1 for signal n), which a child inherits as ignored.
fn ignored_signals() -> u64 {
    let status = fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("SigIgn:"))
        .and_then(|mask| u64::from_str_radix(mask.trim(), 16).ok())
        .unwrap_or(0)
}

/// Runs the binary with its address space limited to `bytes` (prlimit, or
/// `ulimit -v` in sh where prlimit is missing).
fn limited(bytes: u64, args: &[&str], stdin: Option<&Path>) -> Output {
    let prlimit = Command::new("prlimit").arg("--version").output().is_ok_and(|o| o.status.success());
    let mut command = if prlimit {
        let mut c = Command::new("prlimit");
        c.arg(format!("--as={bytes}")).arg(env!("CARGO_BIN_EXE_normalfit"));
        c
    } else {
        let mut c = Command::new("sh");
        c.args(["-c", &format!("ulimit -v {} && exec \"$0\" \"$@\"", bytes / 1024), env!("CARGO_BIN_EXE_normalfit")]);
        c
    };
    command.args(args);
    if let Some(path) = stdin {
        command.stdin(fs::File::open(path).unwrap());
    }
    command.output().unwrap()
}

const GIB: u64 = 1 << 30;

#[test]
fn a_streamed_conversion_fits_in_1_gib_of_address_space() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray16(&input, 4096, 4096);
    let out = dir.path().join("n.png");
    let r = limited(GIB, &["convert", s(&input), "-o", s(&out)], None);
    assert!(r.status.success(), "{:?}: {}", r.status, String::from_utf8_lossy(&r.stderr));
    assert_eq!(image::image_dimensions(&out).unwrap(), (4096, 4096));
}

/// A float EXR of `size`² texels, all 0.5, ZIP-compressed in scan-line
/// blocks or 256² tiles. Every block holds the same texels, so one block
/// is compressed and written everywhere: a 16384² file (1 GiB of floats)
/// takes a moment and about a megabyte.
fn write_constant_exr(path: &Path, size: usize, tiled: bool) {
    use exr::block::chunk::CompressedBlock;
    use exr::block::writer::ChunksWriter;
    use exr::block::{BlockIndex, UncompressedBlock, enumerate_ordered_header_block_indices};
    use exr::compression::Compression;
    use exr::math::RoundingMode;
    use exr::meta::attribute::{ChannelDescription, LevelMode, LineOrder, SampleType, Text, TileDescription};
    use exr::meta::{BlockDescription, header::Header};
    use exr::prelude::{SmallVec, Vec2};

    let blocks = if tiled {
        BlockDescription::Tiles(TileDescription {
            tile_size: Vec2(256, 256),
            level_mode: LevelMode::Singular,
            rounding_mode: RoundingMode::Down,
        })
    } else {
        BlockDescription::ScanLines
    };
    let channels = SmallVec::from_elem(ChannelDescription::named("Y", SampleType::F32), 1);
    let header = Header::new(Text::from("height"), (size, size), channels).with_encoding(
        Compression::ZIP16,
        blocks,
        LineOrder::Increasing,
    );
    let file = BufWriter::new(fs::File::create(path).unwrap());
    exr::block::write(file, SmallVec::from_elem(header, 1), true, |meta, writer| {
        let mut first: Option<(Vec2<usize>, exr::block::chunk::Chunk)> = None;
        for (index, block) in enumerate_ordered_header_block_indices(&meta.headers) {
            let BlockIndex { pixel_position, pixel_size, .. } = block;
            let template = match &first {
                Some((size, chunk)) if *size == pixel_size => chunk.clone(),
                _ => {
                    let data = [0.5f32.to_ne_bytes()].repeat(pixel_size.area()).concat();
                    let chunk = UncompressedBlock { index: block, data }.compress_to_chunk(&meta.headers)?;
                    first = Some((pixel_size, chunk.clone()));
                    chunk
                }
            };
            let mut chunk = template;
            match &mut chunk.compressed_block {
                CompressedBlock::ScanLine(b) => b.y_coordinate = pixel_position.y() as i32,
                CompressedBlock::Tile(t) => {
                    t.coordinates.tile_index = Vec2(pixel_position.x() / 256, pixel_position.y() / 256)
                }
                _ => unreachable!("flat blocks only"),
            }
            writer.write_chunk(index, chunk)?;
        }
        Ok(())
    })
    .unwrap();
}

/// A 16-bit gray PNG of `size`² texels, all the same: tiny on disk, large
/// when decoded whole.
fn write_constant_png16(path: &Path, size: u32) {
    let mut encoder = png::Encoder::new(BufWriter::new(fs::File::create(path).unwrap()), size, size);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let row = [0x40, 0x00].repeat(size as usize);
    for _ in 0..size {
        stream.write_all(&row).unwrap();
    }
    stream.finish().unwrap();
}

/// Checks a conversion under a memory limit: it succeeded with an output
/// of `size`², or it failed cleanly: exit 2, not a signal (an abort is
/// SIGABRT), one line naming `subject` and saying memory is short, and no
/// output.
fn succeeded_or_failed_cleanly(r: &Output, subject: &Path, out: &Path, size: u32) -> bool {
    assert!(r.status.signal().is_none(), "{}: killed by a signal: {:?}", subject.display(), r.status);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(!stderr.contains("memory allocation"), "{stderr}");
    if r.status.success() {
        assert_eq!(image::image_dimensions(out).unwrap(), (size, size));
        true
    } else {
        let line = expect_fault(r, subject, &["memory"]);
        assert!(line.contains("too large"), "{line}");
        assert!(!out.exists(), "{}", out.display());
        false
    }
}

#[test]
fn an_image_too_large_for_the_memory_limit_fails_cleanly_and_never_aborts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("n.png");
    let before = listing(dir.path());
    let mut refused = Vec::new();
    for (tiled, kind) in [(false, "scan-line"), (true, "tiled")] {
        // The same writer's small file converts: the big one is no broken file.
        let small = dir.path().join(format!("small-{kind}.exr"));
        write_constant_exr(&small, 512, tiled);
        let r = limited(GIB, &["convert", s(&small), "-o", s(&out)], None);
        assert!(r.status.success(), "{kind}: {}", String::from_utf8_lossy(&r.stderr));
        assert_eq!(image::image_dimensions(&out).unwrap(), (512, 512));
        fs::remove_file(&out).unwrap();
        fs::remove_file(&small).unwrap();

        // 16384² floats are 1 GiB for the heights alone.
        let big = dir.path().join(format!("big-{kind}.exr"));
        write_constant_exr(&big, 16384, tiled);
        let untouched = Untouched::of(&[&big]);
        let r = limited(GIB, &["convert", s(&big), "-o", s(&out)], None);
        if !succeeded_or_failed_cleanly(&r, &big, &out, 16384) {
            refused.push(kind);
        }
        untouched.check(kind);
        let _ = fs::remove_file(&out);
        fs::remove_file(&big).unwrap();
    }
    // Standard input is read whole, then decoded whole.
    let big = dir.path().join("big.png");
    write_constant_png16(&big, 16384);
    let r = limited(GIB, &["convert", "-", "-o", s(&out)], Some(&big));
    if !succeeded_or_failed_cleanly(&r, Path::new("<standard input>"), &out, 16384) {
        refused.push("png on standard input");
    }
    let _ = fs::remove_file(&out);
    fs::remove_file(&big).unwrap();
    assert_eq!(listing(dir.path()), before, "no output, no temporary file");
    println!("refused under 1 GiB: {refused:?}");
}

/// The whole-image path (standard input is read whole) at a range of
/// limits, from too little to enough: every run converts or is refused
/// with one line, never an abort, into a file and into standard output.
#[test]
fn whole_image_conversions_under_tightening_limits_never_abort() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray16(&input, 2048, 2048);
    let file = dir.path().join("n.png");
    // Every 25 MiB through the range where the encode runs out of room.
    let limits: Vec<u64> = (4..=12).map(|k| k * 25).chain([800]).collect();
    for (args, out) in [
        (&["convert", "-", "-o", s(&file), "--bits", "16"][..], Some(&file)),
        (&["convert", "-", "-o", "-", "--format", "png", "--bits", "16"], None),
    ] {
        let mut converted = Vec::new();
        for &mib in &limits {
            let r = limited(mib << 20, args, Some(&input));
            assert!(r.status.signal().is_none(), "{args:?} at {mib} MiB: {:?}", r.status);
            let stderr = String::from_utf8_lossy(&r.stderr);
            assert!(!stderr.contains("memory allocation") && !stderr.contains("panicked"), "{stderr}");
            if r.status.success() {
                match out {
                    Some(path) => assert_eq!(image::image_dimensions(path).unwrap(), (2048, 2048)),
                    None => {
                        let png = image::load_from_memory(&r.stdout).unwrap();
                        assert_eq!((png.width(), png.height()), (2048, 2048));
                    }
                }
                converted.push(mib);
            } else {
                let errors: Vec<&str> = stderr.lines().filter(|l| !l.starts_with("normalfit: warning: ")).collect();
                assert_eq!(r.status.code(), Some(2), "{stderr}");
                assert_eq!(errors.len(), 1, "{stderr}");
                assert!(errors[0].contains("memory"), "{args:?} at {mib} MiB: {}", errors[0]);
                if let Some(path) = out {
                    assert!(!path.exists(), "no output after a refusal");
                }
            }
            let _ = fs::remove_file(&file);
        }
        assert!(!converted.contains(&limits[0]), "{args:?}: {} MiB is too little, yet it converted", limits[0]);
        assert!(converted.contains(&limits[limits.len() - 1]), "{args:?}: converted only at {converted:?} MiB");
    }
    assert_eq!(listing(dir.path()), ["h.png"]);
}

/// An 8-bit gray PNG of `w` × `h` texels, value (7x + 13y) mod 251 at
/// (x, y): a slope in both directions that wraps, streamed row by row so
/// a 2^26-wide file takes no more memory to write than a row.
fn write_pattern_png8(path: &Path, w: u32, h: u32) {
    let mut encoder = png::Encoder::new(BufWriter::new(fs::File::create(path).unwrap()), w, h);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Fast);
    let mut writer = encoder.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let mut row = vec![0u8; w as usize];
    for y in 0..u64::from(h) {
        for (x, v) in row.iter_mut().enumerate() {
            *v = pattern(x as u64, y);
        }
        stream.write_all(&row).unwrap();
    }
    stream.finish().unwrap();
}

fn pattern(x: u64, y: u64) -> u8 {
    ((7 * x + 13 * y) % 251) as u8
}

/// The contract's 8-bit texel at (x, y) of the pattern image, the fit
/// with N = 3, gain 1 and `border` on both axes, by the slow reference
/// fit over the texel's own 3 × 3 patch (looked up through the border).
fn pattern_texel(w: u64, h: u64, x: u64, y: u64, border: normalfit::Border) -> [u8; 3] {
    use common::reference::{normal_at, source_index};
    let mut patch = Vec::new();
    for j in -1i64..=1 {
        for i in -1i64..=1 {
            let sx = source_index(x as i64 + i, w as i64, border) as u64;
            let sy = source_index(y as i64 + j, h as i64, border) as u64;
            patch.push(f64::from(pattern(sx, sy)) / 255.0);
        }
    }
    // The 3 × 3 patch as an image of its own: its centre's patch is itself.
    let n = normal_at(&patch, 3, 3, &normalfit::Options::new(), 1, 1);
    n.map(|c| (255.0 * (c + 1.0) / 2.0).round() as u8)
}

/// Images of extreme shapes inside the texel limit, under a 1 GiB address
/// space: a column of 2^24 texels and a row of 2^24 convert (streamed
/// from a file, and decoded whole from standard input), with the texels
/// the reference gives; 2^26 × 16 (a 1 GiB raster, whose rows alone are
/// 512 MiB in f64) converts or is refused in one line, never an abort, and
/// leaves no output.
#[test]
fn extreme_shapes_under_1_gib_convert_or_are_refused_in_one_line() {
    use normalfit::Border;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("n.png");
    for (w, h, must_convert) in [(1u32, 1u32 << 24, true), (1 << 24, 1, true), (1 << 26, 16, false)] {
        let input = dir.path().join(format!("{w}x{h}.png"));
        write_pattern_png8(&input, w, h);
        let untouched = Untouched::of(&[&input]);
        for (border, stdin) in [("wrap", false), ("clamp", false), ("mirror", true)] {
            let what = format!("{w}×{h} --border {border}{}", if stdin { " from standard input" } else { "" });
            let args = ["convert", if stdin { "-" } else { s(&input) }, "-o", s(&out), "--border", border];
            let started = Instant::now();
            let r = limited(GIB, &args, stdin.then_some(input.as_path()));
            let took = started.elapsed();
            assert!(r.status.signal().is_none(), "{what}: killed by a signal: {:?}", r.status);
            let stderr = String::from_utf8_lossy(&r.stderr);
            assert!(!stderr.contains("memory allocation") && !stderr.contains("panicked"), "{what}: {stderr}");
            if r.status.success() {
                let raster = normalfit::io::read_path(&out, &Default::default()).unwrap();
                assert_eq!((raster.width, raster.height), (w as usize, h as usize), "{what}");
                let mode = match border {
                    "wrap" => Border::Wrap,
                    "clamp" => Border::Clamp,
                    _ => Border::Mirror,
                };
                let (w, h) = (u64::from(w), u64::from(h));
                let last = w * h - 1;
                for k in [0, 1, 2, w * h / 2 + 3, last - 1, last] {
                    let (x, y) = (k % w, k / w);
                    let got = ["R", "G", "B"]
                        .map(|c| (raster.plane(c).unwrap().data.height(k as usize).unwrap() * 255.0) as u8);
                    let want = pattern_texel(w, h, x, y, mode);
                    // Within the contract's 1e-5 a component at a rounding
                    // tie (0 → 127.5) may round either way.
                    let close = got.iter().zip(&want).all(|(&g, &w)| g.abs_diff(w) <= 1);
                    assert!(close, "{what}: texel ({x}, {y}): {got:?}, the reference {want:?}");
                }
                // A seam check too large for the limit is skipped with a
                // warning line; nothing else is said.
                assert!(stderr.is_empty() || stderr.contains("seam check skipped"), "{what}: {stderr}");
                println!("{what}: converted in {took:.2?} {}", stderr.trim());
                fs::remove_file(&out).unwrap();
            } else {
                assert!(!must_convert, "{what} must convert: {stderr}");
                let subject = if stdin { Path::new("<standard input>") } else { input.as_path() };
                let line = expect_fault(&r, subject, &["memory"]);
                assert!(line.contains("too large"), "{line}");
                assert!(!out.exists(), "{what}: {}", out.display());
                println!("{what}: refused in {took:.2?}: {line}");
            }
        }
        untouched.check(&format!("{w}×{h}"));
        fs::remove_file(&input).unwrap();
    }
    assert_eq!(listing(dir.path()), Vec::<String>::new(), "no output, no temporary file");
}

/// The decoded pixels of an output, as floats, to compare outputs that
/// went different ways (a file's PNG takes its top rows last, a stream's
/// first).
fn pixels(bytes: &[u8]) -> normalfit::io::Raster {
    normalfit::io::decode(bytes, &normalfit::io::ReadOptions::default()).expect("a whole image")
}

/// What `convert` writes into a plain new file, for comparison.
fn reference_output(input: &Path, ext: &str, dir: &Path) -> Vec<u8> {
    let path = dir.join(format!("reference.{ext}"));
    let r = run(&["convert", s(input), "-o", s(&path)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let bytes = fs::read(&path).unwrap();
    fs::remove_file(&path).unwrap();
    bytes
}

#[test]
fn an_output_link_is_followed_and_stays_a_link() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 40, 30);
    let inputs = Untouched::of(&[&input]);
    fs::create_dir(dir.path().join("real")).unwrap();
    for ext in ["png", "exr", "tif"] {
        let want = pixels(&reference_output(&input, ext, dir.path()));
        // A link (relative) to an existing file, a link to that link, and a
        // link to a name with no file yet.
        let target = dir.path().join(format!("real/a.{ext}"));
        fs::write(&target, b"old").unwrap();
        let link = dir.path().join(format!("link.{ext}"));
        std::os::unix::fs::symlink(format!("real/a.{ext}"), &link).unwrap();
        let chain = dir.path().join(format!("chain.{ext}"));
        std::os::unix::fs::symlink(&link, &chain).unwrap();
        let dangling = dir.path().join(format!("dangling.{ext}"));
        std::os::unix::fs::symlink(format!("real/new.{ext}"), &dangling).unwrap();
        for (named, written) in
            [(&link, &target), (&chain, &target), (&dangling, &dir.path().join(format!("real/new.{ext}")))]
        {
            fs::write(&target, b"old").unwrap();
            let r = run(&["convert", s(&input), "-o", s(named)]);
            assert!(r.status.success(), "{}: {}", named.display(), String::from_utf8_lossy(&r.stderr));
            assert!(fs::symlink_metadata(named).unwrap().file_type().is_symlink(), "{} stays a link", named.display());
            assert_eq!(
                pixels(&fs::read(written).unwrap()),
                want,
                "{} is written through {}",
                written.display(),
                named.display()
            );
        }
        assert_eq!(fs::read_link(&link).unwrap(), Path::new(&format!("real/a.{ext}")));
        assert_eq!(fs::read_link(&chain).unwrap(), link);
    }
    let mut names = listing(&dir.path().join("real"));
    names.sort();
    assert_eq!(names, ["a.exr", "a.png", "a.tif", "new.exr", "new.png", "new.tif"], "no temporary file");
    inputs.check("links");
}

/// Runs `args` while a thread reads the FIFO at `fifo` to its end.
fn run_into_fifo(args: &[&str], fifo: &Path) -> (Output, Vec<u8>) {
    let reader = {
        let fifo = fifo.to_path_buf();
        std::thread::spawn(move || fs::read(fifo).unwrap())
    };
    let r = run(args);
    // Replaced by a file, the FIFO would never be written: fail rather
    // than wait for the reader.
    let kind = fs::symlink_metadata(fifo).unwrap().file_type();
    assert!(std::os::unix::fs::FileTypeExt::is_fifo(&kind), "{args:?}: the FIFO was replaced by {kind:?}");
    if !r.status.success() {
        // The reader waits for a writer: give it one that writes nothing.
        drop(fs::OpenOptions::new().write(true).open(fifo));
    }
    (r, reader.join().unwrap())
}

#[test]
fn a_fifo_output_is_written_into_and_stays_a_fifo() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 40, 30);
    let inputs = Untouched::of(&[&input]);
    let fifo = dir.path().join("pipe");
    rustix::fs::mknodat(rustix::fs::CWD, &fifo, rustix::fs::FileType::Fifo, rustix::fs::Mode::from_raw_mode(0o600), 0)
        .unwrap();
    // PNG, and EXR and TIFF, which seek while written: assembled first.
    for format in ["png", "exr", "tiff"] {
        let ext = if format == "tiff" { "tif" } else { format };
        let want = pixels(&reference_output(&input, ext, dir.path()));
        let (r, bytes) = run_into_fifo(&["convert", s(&input), "-o", s(&fifo), "--format", format], &fifo);
        assert!(r.status.success(), "{format}: {}", String::from_utf8_lossy(&r.stderr));
        assert_eq!(pixels(&bytes), want, "{format}");
        assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(), "{format}: the FIFO stays");
    }
    // The lit view, which streams into a file, and the inverse.
    let (r, bytes) = run_into_fifo(&["shade", s(&input), "-o", s(&fifo)], &fifo);
    assert!(r.status.success(), "shade: {}", String::from_utf8_lossy(&r.stderr));
    assert_eq!((pixels(&bytes).width, pixels(&bytes).height), (40, 30));
    // A GeoTIFF band's lit view, which streams into a file: into the
    // FIFO, the same pixels, read whole.
    let dem = dir.path().join("dem.tif");
    write_dem(&dem);
    let lit = dir.path().join("lit.png");
    assert!(run(&["shade", s(&dem), "-o", s(&lit), "--units", "map"]).status.success());
    let (r, bytes) = run_into_fifo(&["shade", s(&dem), "-o", s(&fifo), "--units", "map"], &fifo);
    assert!(r.status.success(), "shade of a DEM: {}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(pixels(&bytes), pixels(&fs::read(&lit).unwrap()), "shade of a DEM");
    // The DEM, its lit view and the lit view's sidecars (none beside the FIFO).
    for made in fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().path()) {
        let name = made.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("dem.") || name.starts_with("lit.") {
            fs::remove_file(&made).unwrap();
        }
    }
    let normals = dir.path().join("n.png");
    assert!(run(&["convert", s(&input), "-o", s(&normals)]).status.success());
    let (r, bytes) = run_into_fifo(&["height", s(&normals), "-o", s(&fifo), "--format", "exr"], &fifo);
    assert!(r.status.success(), "height: {}", String::from_utf8_lossy(&r.stderr));
    assert_eq!((pixels(&bytes).width, pixels(&bytes).height), (40, 30));
    assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    let mut names = listing(dir.path());
    names.sort();
    assert_eq!(names, ["h.png", "n.png", "pipe"], "no temporary file, no sidecar");
    inputs.check("fifo");
}

#[test]
fn dev_stdout_as_the_output_writes_to_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 40, 30);
    let want = pixels(&reference_output(&input, "png", dir.path()));
    let r = run(&["convert", s(&input), "-o", "/dev/stdout", "--format", "png"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(pixels(&r.stdout), want);
    assert_eq!(listing(dir.path()), ["h.png"]);
}

#[test]
#[ignore = "needs root to make a device node; CI runs as root with --include-ignored"]
fn a_device_output_is_written_into_not_replaced() {
    use std::os::unix::fs::FileTypeExt;
    assert!(is_root(), "run as root: a device node (a copy of /dev/null) is made in a temporary folder");
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray8(&input, 40, 30);
    // A GeoTIFF band streams where a PNG's lit view is read whole.
    let dem = dir.path().join("dem.tif");
    write_dem(&dem);
    let inputs = Untouched::of(&[&input, &dem]);
    // A null device of the test's own, so that a failure cannot replace
    // the system's /dev/null.
    let null = dir.path().join("null");
    rustix::fs::mknodat(
        rustix::fs::CWD,
        &null,
        rustix::fs::FileType::CharacterDevice,
        rustix::fs::Mode::from_raw_mode(0o666),
        rustix::fs::makedev(1, 3),
    )
    .unwrap();
    let link = dir.path().join("null-link");
    std::os::unix::fs::symlink(&null, &link).unwrap();
    for named in [&null, &link] {
        for args in [
            vec!["convert", s(&input), "-o", s(named), "--format", "png"],
            vec!["convert", s(&input), "-o", s(named), "--format", "exr"],
            vec!["convert", s(&input), "-o", s(named), "--format", "tiff"],
            vec!["shade", s(&input), "-o", s(named)],
            vec!["shade", s(&dem), "-o", s(named)],
            vec!["shade", s(&dem), "-o", s(named), "--units", "map"],
            vec!["convert", s(&dem), "-o", s(named), "--units", "map"],
        ] {
            let r = run(&args);
            assert!(r.status.success(), "{args:?}: {}", String::from_utf8_lossy(&r.stderr));
            let meta = fs::metadata(&null).unwrap();
            assert!(
                meta.file_type().is_char_device() && meta.rdev() == rustix::fs::makedev(1, 3),
                "{args:?}: still the device"
            );
        }
    }
    assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    let mut names = listing(dir.path());
    names.sort();
    assert_eq!(names, ["dem.tif", "h.png", "null", "null-link"], "no temporary file, no sidecar");
    inputs.check("device");
}

/// A georeferenced 16² float DEM (UTM, 30 m texels) at `path`.
fn write_dem(path: &Path) {
    use common::geotiff::{self, Kind, Layout};
    let heights: Vec<f64> = (0..16 * 16).map(|i| f64::from((i % 16) * (i / 16)) * 0.7).collect();
    fs::write(path, geotiff::write(16, 16, &Layout::gray(Kind::F32), &[heights], &geotiff::utm_tags())).unwrap();
}

/// A sidecar is checked against the inputs before anything is written: a
/// GeoTIFF named as the output's world file is refused (the output is
/// not written either), as is one named as its `.aux.xml`.
#[test]
fn a_sidecar_that_is_the_input_is_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    for (input_name, output_name) in [("x.pgw", "x.png"), ("y.png.aux.xml", "y.png")] {
        let input = dir.path().join(input_name);
        write_dem(&input);
        let inputs = Untouched::of(&[&input]);
        let before = listing(dir.path());
        let output = dir.path().join(output_name);
        for command in ["convert", "shade"] {
            let r = run(&[command, s(&input), "-o", s(&output), "--units", "map"]);
            let line = expect_fault(&r, &output, &["is the input"]);
            assert!(line.contains(input_name), "names the sidecar: {line}");
            inputs.check(&format!("{command} {input_name}"));
            assert_eq!(listing(dir.path()), before, "{command} {input_name}: nothing written");
        }
    }
}

/// `--overwrite never` keeps an existing sidecar: the batch writes
/// nothing for that input (not the image beside the old world file), and
/// goes on with the others.
#[test]
fn overwrite_never_keeps_an_existing_sidecar_and_its_image_is_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.tif"), dir.path().join("b.tif"));
    write_dem(&a);
    write_dem(&b);
    let out = dir.path().join("out");
    fs::create_dir(&out).unwrap();
    let kept = out.join("a_normal.pgw");
    fs::write(&kept, b"kept").unwrap();
    let r = run(&["convert", s(&a), s(&b), "-o", s(&out), "--format", "png", "--overwrite", "never"]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(stderr.contains("a_normal.pgw exists and is kept"), "{stderr}");
    assert_eq!(fs::read(&kept).unwrap(), b"kept");
    assert_eq!(listing(&out), ["a_normal.pgw", "b_normal.pgw", "b_normal.png", "b_normal.png.aux.xml"]);
    // b's outputs are there now: a second run keeps them, and skips b.
    let b_png = fs::read(out.join("b_normal.png")).unwrap();
    let r = run(&["convert", s(&b), "-o", s(&out), "--format", "png", "--overwrite", "never"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(fs::read(out.join("b_normal.png")).unwrap(), b_png);
}

/// A full disk part way through a georeferenced output leaves the old
/// image and the old sidecars as they were, and nothing else: the files
/// are named together or not at all.
#[test]
#[ignore = "needs root to mount a small tmpfs; CI runs as root with --include-ignored"]
fn a_full_disk_leaves_the_old_image_and_its_old_sidecars() {
    assert!(is_root(), "needs root to mount a small tmpfs");
    let dir = tempfile::tempdir().unwrap();
    // 1024² float heights of noise, georeferenced: neither their normal
    // map nor their lit view fits in 256 KiB.
    let input = dir.path().join("dem.tif");
    let noise = |i: u64| (i.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40) as f64 / 1e3;
    let heights: Vec<f64> = (0..1024 * 1024).map(noise).collect();
    let layout = common::geotiff::Layout::gray(common::geotiff::Kind::F32);
    fs::write(&input, common::geotiff::write(1024, 1024, &layout, &[heights], &common::geotiff::utm_tags())).unwrap();
    let small = dir.path().join("small");
    let mount = Mount::tmpfs(&small, "size=256k").unwrap_or_else(|why| panic!("no small file system to fill: {why}"));
    let (image, world, aux) = (small.join("n.png"), small.join("n.pgw"), small.join("n.png.aux.xml"));
    for (path, bytes) in [(&image, &b"old image"[..]), (&world, b"old world"), (&aux, b"old aux")] {
        fs::write(path, bytes).unwrap();
    }
    for command in ["convert", "shade"] {
        let r = run(&[command, s(&input), "-o", s(&image), "--units", "map", "--border", "clamp"]);
        expect_fault(&r, &image, &["no space"]);
        assert_eq!(fs::read(&image).unwrap(), b"old image", "{command}");
        assert_eq!(fs::read(&world).unwrap(), b"old world", "{command}");
        assert_eq!(fs::read(&aux).unwrap(), b"old aux", "{command}");
        assert_eq!(listing(&small), ["n.pgw", "n.png", "n.png.aux.xml"], "{command}: nothing else");
    }
    drop(mount);
}

/// The residual beside a normal map: when the disk fills after the
/// normal map is written and before the residual is, both keep their old
/// content (the normal map was replaced before the two were named
/// together).
#[test]
#[ignore = "needs root to mount a small tmpfs; CI runs as root with --include-ignored"]
fn a_full_disk_after_the_normal_map_leaves_it_and_its_residual_as_they_were() {
    assert!(is_root(), "needs root to mount a small tmpfs");
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("h.png");
    write_gray16(&input, 256, 256);
    let args = |map: &Path, residual: &Path| {
        let (map, residual) = (s(map).to_string(), s(residual).to_string());
        let input = s(&input).to_string();
        run(&["convert", &input, "--scale", "200", "--bits", "8", "-o", &map, "--residual", &residual])
    };
    // Where there is room: the sizes.
    let (roomy_map, roomy_residual) = (dir.path().join("n.png"), dir.path().join("r.exr"));
    let r = args(&roomy_map, &roomy_residual);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let pages = |path: &Path| fs::metadata(path).unwrap().len().div_ceil(4096);
    let (map_pages, residual_pages) = (pages(&roomy_map), pages(&roomy_residual));
    assert!(residual_pages > 4, "the residual takes {residual_pages} pages");
    // Room for the old files and the new normal map, not the residual.
    let small = dir.path().join("small");
    let size = format!("size={}k", 4 * (map_pages + 4));
    let mount = Mount::tmpfs(&small, &size).unwrap_or_else(|why| panic!("no small file system to fill: {why}"));
    let (map, residual) = (small.join("n.png"), small.join("r.exr"));
    fs::write(&map, b"old map").unwrap();
    fs::write(&residual, b"old residual").unwrap();
    let r = args(&map, &residual);
    expect_fault(&r, &residual, &["no space"]);
    assert_eq!(fs::read(&map).unwrap(), b"old map");
    assert_eq!(fs::read(&residual).unwrap(), b"old residual");
    assert_eq!(listing(&small), ["n.png", "r.exr"], "nothing else");
    drop(mount);
}
