//! A PNG conversion against its codec floor (issue 36, point 6), side by
//! side in one run, turn about: a 16-bit PNG height map to an 8-bit RGB
//! normal map (wrap borders, the fast setting, `--relief 0.03`), file to
//! memory.
//!
//! * decode: the input's rows decoded alone ([`PngRows`], the conversion's
//!   reader), into one row;
//! * encode: the conversion's normals, made beforehand, filtered, deflated
//!   in pieces and written as the conversion writes them, from rows held
//!   in memory ([`png_codec_floor`]);
//! * floor: the two overlapped as the conversion overlaps them: the same
//!   run with the rows decoded from the file and the fit replaced by a copy
//!   of the normals;
//! * convert: the conversion itself ([`convert_png_seekable`]), and with a
//!   path to the `normalfit` binary, the command line's (`normalfit convert
//!   INPUT --relief 0.03 --bits 8`, which adds the seam check and the file).
//!
//! Prints each one's least and median wall time over the rounds (each
//! round runs them all, one after another) and the conversion over the
//! floor. The floor's file is checked to be the conversion's, byte for
//! byte: the same encoding work.
//!
//! `cargo run --release --example codec_floor -- INPUT.png [ROUNDS] [BINARY]`

use std::io::Cursor;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use normalfit::io::ReadOptions;
use normalfit::pipeline::{PngDepth, PngOptions, PngRows, RowSource, convert_png_seekable, png_codec_floor};
use normalfit::{Options, Strength};

fn open(path: &Path) -> PngRows {
    PngRows::open(path, &ReadOptions::default(), None).expect("a readable PNG").expect("a PNG that streams")
}

/// The input's heights held in memory, given again row by row.
struct Held {
    heights: Vec<f32>,
    width: usize,
    unit: f64,
    next: usize,
}

impl RowSource for Held {
    fn width(&self) -> usize {
        self.width
    }
    fn height(&self) -> usize {
        self.heights.len() / self.width
    }
    fn unit(&self) -> f64 {
        self.unit
    }
    fn exact_in_f32(&self) -> bool {
        true
    }
    fn next_row(&mut self, out: &mut [f64]) -> normalfit::Result<()> {
        let row = &self.heights[self.next * self.width..][..self.width];
        out.iter_mut().zip(row).for_each(|(o, &v)| *o = f64::from(v));
        self.next += 1;
        Ok(())
    }
    fn next_row_f32(&mut self, out: &mut [f32]) -> normalfit::Result<()> {
        out.copy_from_slice(&self.heights[self.next * self.width..][..self.width]);
        self.next += 1;
        Ok(())
    }
}

fn convert(path: &Path, opts: &Options) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    convert_png_seekable(open(path), opts, PngOptions::new(PngDepth::Eight), |_| {}, &mut out).unwrap();
    out.into_inner()
}

fn floor(rows: impl RowSource, opts: &Options, texels: &[[u8; 3]]) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    png_codec_floor(rows, opts, texels, &mut out).unwrap();
    out.into_inner()
}

fn decode(path: &Path) -> Held {
    let mut rows = open(path);
    let (width, height, unit) = (rows.width(), rows.height(), rows.unit());
    let mut heights = vec![0f32; width * height];
    for row in heights.chunks_exact_mut(width) {
        rows.next_row_f32(row).unwrap();
    }
    Held { heights, width, unit, next: 0 }
}

/// The input's rows decoded into one row, as the conversion's decoding
/// thread reads them (into bands it fills again).
fn decode_alone(path: &Path) {
    let mut rows = open(path);
    let mut row = vec![0f32; rows.width()];
    for _ in 0..rows.height() {
        rows.next_row_f32(&mut row).unwrap();
    }
}

fn seconds(run: impl FnOnce()) -> f64 {
    let start = Instant::now();
    run();
    start.elapsed().as_secs_f64()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let input = Path::new(args.first().expect("usage: codec_floor INPUT.png [ROUNDS] [BINARY]"));
    let rounds: usize = args.get(1).map_or(7, |r| r.parse().expect("ROUNDS: a number"));
    let binary = args.get(2);
    let opts = Options::new().with_strength(Strength::Relief(0.03));

    // The conversion's own normals, read back from its file.
    let converted = convert(input, &opts);
    let texels: Vec<[u8; 3]> =
        image::load_from_memory(&converted).expect("the conversion's PNG").to_rgb8().pixels().map(|p| p.0).collect();
    assert!(floor(open(input), &opts, &texels) == converted, "the floor's file is the conversion's");
    let held = decode(input);
    assert!(floor(Held { next: 0, ..held }, &opts, &texels) == converted, "so is the encoder's alone");
    let cli_out = std::env::temp_dir().join(format!("codec_floor_{}.png", std::process::id()));

    let names = ["decode", "encode", "floor", "convert", "command line"];
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for _ in 0..rounds {
        times[0].push(seconds(|| decode_alone(input)));
        // The heights read before the clock starts: the encoder's alone.
        let held = decode(input);
        times[1].push(seconds(|| drop(floor(held, &opts, &texels))));
        times[2].push(seconds(|| drop(floor(open(input), &opts, &texels))));
        times[3].push(seconds(|| drop(convert(input, &opts))));
        if let Some(binary) = binary {
            let _ = std::fs::remove_file(&cli_out);
            times[4].push(seconds(|| {
                let status = Command::new(binary)
                    .arg("convert")
                    .arg(input)
                    .args(["--relief", "0.03", "--bits", "8", "-o"])
                    .arg(&cli_out)
                    .status()
                    .expect("the binary runs");
                assert!(status.success(), "the command line converts");
            }));
        }
    }
    let _ = std::fs::remove_file(&cli_out);
    let summary = |t: &[f64]| {
        let mut sorted = t.to_vec();
        sorted.sort_by(f64::total_cmp);
        (sorted[0], sorted[sorted.len() / 2])
    };
    println!("{} rounds, {}", rounds, input.display());
    println!("| | least | median |\n|---|---:|---:|");
    for (name, t) in names.iter().zip(&times).filter(|(_, t)| !t.is_empty()) {
        let (least, median) = summary(t);
        println!("| {name} | {:.1} ms | {:.1} ms |", least * 1e3, median * 1e3);
    }
    let (floor_least, floor_median) = summary(&times[2]);
    for k in [3, 4].into_iter().filter(|&k| !times[k].is_empty()) {
        let (least, median) = summary(&times[k]);
        println!("{} ÷ floor: {:.2} (least), {:.2} (medians)", names[k], least / floor_least, median / floor_median);
    }
}
