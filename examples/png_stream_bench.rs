//! The streaming path's PNG encoder against the `png` crate's
//! `StreamWriter`, on one 4096² streamed conversion of a 16-bit PNG height
//! map (8-bit RGB out, wrap borders, the fast setting), file to memory,
//! alternating runs and printing medians:
//!
//! * ours: [`PngRows`] into [`convert_png_seekable`]: one pass over the
//!   input, the top rows fitted last into room kept after the header,
//!   rows filtered and deflated (fdeflate, in pieces) in parallel on the
//!   fit's side;
//! * png: what `StreamWriter` needs, rows in order: a first pass for the
//!   wrap's tail rows ([`RowSource::read_tail`]), a second that decodes
//!   the rows, the fit band by band ([`BandFit`]), each band written to
//!   `png::StreamWriter` with `FdeflateUltraFast` and the Avg filter (ours
//!   at `--compression fast`), or its adaptive filter. (The rows are kept
//!   whole here, which only flatters it: a streaming version would keep a
//!   window.)
//!
//! `cargo run --release --example png_stream_bench -- [SIZE] [RUNS]`
//!
//! Both outputs are decoded and compared texel for texel.

use std::io::Cursor;
use std::path::Path;
use std::time::Instant;

use normalfit::Options;
use normalfit::fit::BandFit;
use normalfit::io::ReadOptions;
use normalfit::pipeline::{PngDepth, PngOptions, PngRows, RowSource, convert_png_seekable};

fn open(path: &Path) -> PngRows {
    PngRows::open(path, &ReadOptions::default(), None).unwrap().expect("a PNG that streams")
}

fn ours(path: &Path, opts: &Options) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    let png = PngOptions::new(PngDepth::Eight);
    convert_png_seekable(open(path), opts, png, |_| {}, &mut out).unwrap();
    out.into_inner()
}

fn theirs(path: &Path, opts: &Options, filter: png::Filter) -> Vec<u8> {
    let rows = open(path);
    let (w, h, unit) = (rows.width(), rows.height(), rows.unit());
    let fit = BandFit::new(w, h, opts).unwrap().with_unit(unit);
    // The first pass: StreamWriter takes the top rows first, and with a
    // wrap in y they need the last ones.
    let _tail = rows.read_tail(fit.radius(), |_| {}).unwrap();
    let mut rows = open(path);
    let mut heights = vec![0f32; w * h];
    for row in heights.chunks_exact_mut(w) {
        rows.next_row_f32(row).unwrap();
    }
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, w as u32, h as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_deflate_compression(png::DeflateCompression::FdeflateUltraFast);
    encoder.set_filter(filter);
    let mut writer = encoder.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let row = |y: usize| &heights[y * w..][..w];
    for band in fit.bands() {
        let mut normals = vec![[0u8; 3]; band.len() * w];
        fit.fit_band(band, &row, &mut normals).unwrap();
        std::io::Write::write_all(&mut stream, normals.as_flattened()).unwrap();
    }
    stream.finish().unwrap();
    writer.finish().unwrap();
    out
}

/// A 16-bit height map with grain, as in a scanned or sculpted texture
/// (without it the map deflates to nothing and only the fit is timed).
fn write_height(path: &Path, size: usize) {
    let tau = std::f64::consts::TAU;
    let mut bytes = Vec::with_capacity(2 * size * size);
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    for k in 0..size * size {
        let (u, v) = ((k % size) as f64 / size as f64, (k / size) as f64 / size as f64);
        let h = 0.5 + 0.2 * (tau * (3.0 * u + 2.0 * v)).sin() + 0.1 * (tau * 37.0 * u).cos() * (tau * 23.0 * v).sin();
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let grain = (seed >> 56) as f64 * 4.0;
        bytes.extend_from_slice(&((h * 60000.0 + grain).round() as u16).to_be_bytes());
    }
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut encoder = png::Encoder::new(file, size as u32, size as u32);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Sixteen);
    encoder.write_header().unwrap().write_image_data(&bytes).unwrap();
}

fn decode(bytes: &[u8]) -> Vec<u8> {
    let mut reader = png::Decoder::new(Cursor::new(bytes)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf).unwrap();
    buf
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let size: usize = args.next().map_or(4096, |a| a.parse().expect("SIZE"));
    let runs: usize = args.next().map_or(5, |a| a.parse().expect("RUNS"));
    let dir = std::env::temp_dir().join(format!("normalfit-png-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("height.png");
    write_height(&path, size);
    let opts = Options::default();

    let a = ours(&path, &opts);
    let b = theirs(&path, &opts, png::Filter::Avg);
    assert!(decode(&a) == decode(&b), "the two encoders wrote different texels");
    let mut times: [Vec<f64>; 3] = Default::default();
    let mut bytes = [0usize; 3];
    for _ in 0..runs {
        for (k, times) in times.iter_mut().enumerate() {
            let start = Instant::now();
            let out = match k {
                0 => ours(&path, &opts),
                1 => theirs(&path, &opts, png::Filter::Avg),
                _ => theirs(&path, &opts, png::Filter::Adaptive),
            };
            times.push(start.elapsed().as_secs_f64());
            bytes[k] = out.len();
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
    for (k, name) in
        ["ours (one pass, parallel filters, deflate)", "png StreamWriter, Avg", "png StreamWriter, adaptive"]
            .iter()
            .enumerate()
    {
        println!(
            "{size}²  {name:<34} median {:.3} s of {runs}  {:.1} MiB",
            median(times[k].clone()),
            bytes[k] as f64 / (1 << 20) as f64
        );
    }
}
