//! GPU textures (`normalfit::io::gpu`) read back by readers written here
//! from the specifications, apart from the writers: a KTX 2.0 reader (the
//! Khronos KTX 2.0 specification: identifier, header, index, level index,
//! Data Format Descriptor), a DDS reader (Microsoft's DDS_HEADER and
//! DDS_HEADER_DXT10), and a BC4/BC5 block decoder (the Khronos Data Format
//! Specification's BC4 section). Pillow's DDS reader, an independent
//! decoder, decodes BC4, BC5, BC7 and RGBA8 levels (ignored where python3
//! has no Pillow: set `NORMALFIT_PYTHON` to an interpreter that has it).

use normalfit::Error;
use normalfit::io::gpu::{
    Chain, Compression, Container, EncodedChain, MipLevel, TextureFormat, Uncompressed, encode_chain, write_chain,
    write_chain_file,
};
use normalfit::mips::{average_chain, box_levels, level_sizes, mean_lengths};

// ---------------------------------------------------------------- inputs

/// Unit normals of a field of bumps, tilted differently everywhere, with
/// components across most of [−1, 1].
fn bumpy(width: usize, height: usize) -> Vec<[f32; 3]> {
    bumps(width, height, 1.0)
}

/// [`bumpy`]'s field with its bumps `spread` times wider.
fn bumps(width: usize, height: usize, spread: f64) -> Vec<[f32; 3]> {
    (0..width * height)
        .map(|k| {
            let (x, y) = ((k % width) as f64 / spread, (k / width) as f64 / spread);
            let dx = 1.8 * (x * 0.31).sin() + 0.7 * (y * 0.17 + x * 0.05).cos();
            let dy = 1.5 * (y * 0.23).cos() - 0.6 * (x * 0.11).sin();
            let len = (dx * dx + dy * dy + 1.0).sqrt();
            [(-dx / len) as f32, (-dy / len) as f32, (1.0 / len) as f32]
        })
        .collect()
}

fn normals_chain(width: usize, height: usize) -> Vec<MipLevel<[f32; 3]>> {
    average_chain(&bumpy(width, height), (width, height)).unwrap()
}

fn values_chain(width: usize, height: usize) -> Vec<MipLevel<f32>> {
    mean_lengths(&bumpy(width, height), (width, height)).unwrap()
}

/// Heights in [0, 1] (a slope and a wave) box-filtered down the chain: an
/// alpha of heights.
fn heights_chain(width: usize, height: usize) -> Vec<MipLevel<f32>> {
    let values: Vec<f64> = (0..width * height)
        .map(|k| {
            let (x, y) = ((k % width) as f64 / width as f64, (k / width) as f64 / height as f64);
            0.2 + 0.4 * x + 0.25 * (0.5 + 0.5 * (3.0 * y + x).sin())
        })
        .collect();
    let levels = box_levels(&values, (width, height), usize::MAX).unwrap();
    levels
        .into_iter()
        .map(|l| MipLevel { width: l.width, height: l.height, texels: l.texels.iter().map(|&v| v as f32).collect() })
        .collect()
}

/// An alpha's byte: round(255 a), a in [0, 1].
fn alpha_byte(a: f32) -> u8 {
    (f64::from(a) * 255.0).round() as u8
}

/// A normal's component as the 8-bit encoding codes it, unrounded.
fn code(c: f32) -> f64 {
    (f64::from(c) + 1.0) * 127.5
}

/// The 8-bit encoding: round((c + 1) · 127.5), ties to even.
fn byte(c: f32) -> u8 {
    code(c).round_ties_even() as u8
}

fn half(v: f32) -> [u8; 2] {
    half::f16::from_f32(v).to_le_bytes()
}

// ------------------------------------------------------------- decoders

/// BC4 (unsigned) block → 16 values in [0, 255], as the Khronos Data
/// Format Specification defines it: two 8-bit endpoints, then 16 3-bit
/// indices, little-endian; red0 > red1 selects 8 interpolated values, else
/// 6 and the constants 0 and 255.
fn decode_bc4(block: &[u8]) -> [f64; 16] {
    let (r0, r1) = (f64::from(block[0]), f64::from(block[1]));
    let mut bits = 0u64;
    for (i, b) in block[2..8].iter().enumerate() {
        bits |= u64::from(*b) << (8 * i);
    }
    let mut out = [0.0; 16];
    for (i, v) in out.iter_mut().enumerate() {
        let index = (bits >> (3 * i)) & 7;
        *v = match index {
            0 => r0,
            1 => r1,
            i if r0 > r1 => ((8 - i) as f64 * r0 + (i - 1) as f64 * r1) / 7.0,
            6 => 0.0,
            7 => 255.0,
            i => ((6 - i) as f64 * r0 + (i - 1) as f64 * r1) / 5.0,
        };
    }
    out
}

/// Per texel of a `w × h` level of BC4 or BC5 blocks: each channel's
/// decoded value (the texels past the edge dropped).
fn decode_bc_level(bytes: &[u8], (w, h): (usize, usize), channels: usize) -> Vec<Vec<f64>> {
    let across = w.div_ceil(4);
    let mut out = vec![vec![0.0; channels]; w * h];
    for (b, block) in bytes.chunks_exact(8 * channels).enumerate() {
        let (bx, by) = (b % across, b / across);
        for c in 0..channels {
            let values = decode_bc4(&block[8 * c..8 * c + 8]);
            for (i, v) in values.iter().enumerate() {
                let (x, y) = (bx * 4 + i % 4, by * 4 + i / 4);
                if x < w && y < h {
                    out[y * w + x][c] = *v;
                }
            }
        }
    }
    out
}

/// The bound of a BC4 channel: half a step of the ramp spanning the
/// block's values (a seventh of the range), plus the endpoints' rounding
/// (one code). Each texel is checked against its own block's.
fn bc_bound(values: &[f64]) -> f64 {
    let (lo, hi) = values.iter().fold((f64::MAX, f64::MIN), |(l, h), &v| (l.min(v), h.max(v)));
    (hi - lo) / 14.0 + 1.0
}

/// Checks decoded BC4/BC5 texels against the source values (`source(i)`:
/// the channels of texel i in code units), each within its block's bound.
#[allow(clippy::needless_range_loop, reason = "c indexes each texel's channels, not `decoded`")]
fn check_bc(decoded: &[Vec<f64>], (w, h): (usize, usize), source: impl Fn(usize) -> Vec<f64>, what: &str) {
    for by in 0..h.div_ceil(4) {
        for bx in 0..w.div_ceil(4) {
            let texels: Vec<usize> = (0..16)
                .map(|i| (by * 4 + i / 4, bx * 4 + i % 4))
                .filter(|&(y, x)| x < w && y < h)
                .map(|(y, x)| y * w + x)
                .collect();
            for c in 0..decoded[0].len() {
                // The block's source values include the repeated edge,
                // which are the same texels: the bound of the real ones.
                let values: Vec<f64> = texels.iter().map(|&t| source(t)[c]).collect();
                let bound = bc_bound(&values);
                for &t in &texels {
                    let (want, got) = (source(t)[c], decoded[t][c]);
                    assert!(
                        (want - got).abs() <= bound,
                        "{what}: texel ({}, {}) channel {c}: {want:.3} decoded {got:.3}, bound {bound:.3}",
                        t % w,
                        t / w
                    );
                }
            }
        }
    }
}

// ------------------------------------------------------------ KTX2 reader

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn u64_at(b: &[u8], at: usize) -> usize {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap()) as usize
}

/// What a KTX2 file says, read as the specification lays it out.
#[derive(Debug)]
struct Ktx2 {
    vk_format: u32,
    type_size: u32,
    width: u32,
    height: u32,
    depth: u32,
    layers: u32,
    faces: u32,
    level_count: u32,
    supercompression: u32,
    dfd: Vec<u32>,
    /// (byteOffset, byteLength, uncompressedByteLength), level 0 first.
    levels: Vec<(usize, usize, usize)>,
}

fn read_ktx2(file: &[u8]) -> Ktx2 {
    assert_eq!(file[..12], [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A], "identifier");
    let h: Vec<u32> = (0..9).map(|i| u32_at(file, 12 + 4 * i)).collect();
    let (dfd_offset, dfd_length) = (u32_at(file, 48) as usize, u32_at(file, 52) as usize);
    let (kvd_offset, kvd_length) = (u32_at(file, 56) as usize, u32_at(file, 60) as usize);
    assert_eq!((u64_at(file, 64), u64_at(file, 72)), (0, 0), "no supercompression global data");
    let level_count = h[7].max(1) as usize;
    let levels: Vec<_> = (0..level_count)
        .map(|k| (u64_at(file, 80 + 24 * k), u64_at(file, 88 + 24 * k), u64_at(file, 96 + 24 * k)))
        .collect();
    assert_eq!(dfd_offset, 80 + 24 * level_count, "the DFD follows the level index");
    assert_eq!(dfd_offset % 4, 0);
    assert_eq!(kvd_offset % 4, 0);
    if kvd_length > 0 {
        assert_eq!(kvd_offset, dfd_offset + dfd_length, "the key/value data follows the DFD");
        // Each entry: its length, then key NUL value, padded to 4.
        let mut at = kvd_offset;
        while at < kvd_offset + kvd_length {
            let n = u32_at(file, at) as usize;
            let entry = &file[at + 4..at + 4 + n];
            let key_end = entry.iter().position(|&b| b == 0).expect("a key ends in NUL");
            assert!(!entry[..key_end].is_empty());
            at = (at + 4 + n).next_multiple_of(4);
        }
        assert_eq!(at, kvd_offset + kvd_length, "kvdByteLength covers the entries and their padding");
    }
    let dfd: Vec<u32> = (0..dfd_length / 4).map(|i| u32_at(file, dfd_offset + 4 * i)).collect();
    Ktx2 {
        vk_format: h[0],
        type_size: h[1],
        width: h[2],
        height: h[3],
        depth: h[4],
        layers: h[5],
        faces: h[6],
        level_count: h[7],
        supercompression: h[8],
        dfd,
        levels,
    }
}

/// The numbers the KTX2 file of each format must hold: vkFormat,
/// typeSize, texel block side, bytes a block, the DFD's colour model and
/// sample count.
fn ktx2_expectations(format: TextureFormat) -> (u32, u32, usize, usize, u32, usize) {
    match format {
        TextureFormat::Bc4 => (139, 1, 4, 8, 131, 1),
        TextureFormat::Bc5 => (141, 1, 4, 16, 132, 2),
        TextureFormat::Bc7 => (145, 1, 4, 16, 134, 1),
        TextureFormat::Rgba8 => (37, 1, 1, 4, 1, 4),
        TextureFormat::Rg8 => (16, 1, 1, 2, 1, 2),
        TextureFormat::R8 => (9, 1, 1, 1, 1, 1),
        TextureFormat::Rgba16f => (97, 2, 1, 8, 1, 4),
        TextureFormat::Rg16f => (83, 2, 1, 4, 1, 2),
        TextureFormat::R16f => (76, 2, 1, 2, 1, 1),
        #[allow(unreachable_patterns)]
        other => panic!("no expectations for {other:?}"),
    }
}

/// Checks a KTX2 file of `chain`'s sizes in `format` and returns each
/// level's bytes, level 0 first.
fn check_ktx2(file: &[u8], format: TextureFormat, sizes: &[(usize, usize)]) -> Vec<Vec<u8>> {
    let k = read_ktx2(file);
    let (vk, type_size, side, block_bytes, model, samples) = ktx2_expectations(format);
    assert_eq!((k.vk_format, k.type_size), (vk, type_size), "{format:?}");
    assert_eq!((k.width as usize, k.height as usize), sizes[0]);
    assert_eq!((k.depth, k.layers, k.faces, k.supercompression), (0, 0, 1, 0));
    assert_eq!(k.level_count as usize, sizes.len());
    // The DFD: total size, then the basic block's header.
    let block_size = 24 + 16 * samples;
    assert_eq!(k.dfd[0] as usize, 4 + block_size, "dfdTotalSize");
    assert_eq!(k.dfd.len() * 4, 4 + block_size);
    assert_eq!(k.dfd[1], 0, "vendorId 0, descriptorType 0");
    assert_eq!(k.dfd[2], 2 | (block_size as u32) << 16, "versionNumber 2, descriptorBlockSize");
    assert_eq!(k.dfd[3] & 0xFF, model, "colorModel");
    assert_eq!((k.dfd[3] >> 8) & 0xFF, 1, "colorPrimaries BT.709");
    assert_eq!((k.dfd[3] >> 16) & 0xFF, 1, "transferFunction linear");
    let dim = (side - 1) as u32;
    assert_eq!(k.dfd[4], dim | dim << 8, "texelBlockDimension");
    assert_eq!(k.dfd[5], block_bytes as u32, "bytesPlane0");
    // The first sample: bit offset 0, its length, and the last sample ends
    // at the block's last bit.
    assert_eq!(k.dfd[7] & 0xFFFF, 0);
    let last = 7 + 4 * (samples - 1);
    let (offset, length) = (k.dfd[last] & 0xFFFF, (k.dfd[last] >> 16) & 0xFF);
    assert_eq!((offset + length + 1) as usize, 8 * block_bytes, "samples cover the block");
    // The level index and the data.
    let align = match block_bytes % 4 {
        0 => block_bytes,
        2 => 2 * block_bytes,
        _ => 4 * block_bytes,
    };
    let mut out = Vec::new();
    for (level, (&(offset, length, uncompressed), &(w, h))) in k.levels.iter().zip(sizes).enumerate() {
        let blocks = w.div_ceil(side) * h.div_ceil(side);
        assert_eq!(length, blocks * block_bytes, "level {level} ({w} × {h}) of {format:?}");
        assert_eq!(uncompressed, length);
        assert_eq!(offset % align, 0, "level {level} at {offset}, not a multiple of {align}");
        if level + 1 < k.levels.len() {
            let smaller = k.levels[level + 1];
            assert!(smaller.0 + smaller.1 <= offset, "level {} is stored before level {level}", level + 1);
        }
        out.push(file[offset..offset + length].to_vec());
    }
    assert_eq!(k.levels[0].0 + k.levels[0].1, file.len(), "level 0 ends the file");
    out
}

// ------------------------------------------------------------- DDS reader

/// A DDS file's size, mip count, DXGI format and each level's bytes (at
/// offsets the test computes: 148 bytes of header, then the levels in
/// order, each its blocks' bytes).
fn read_dds(file: &[u8], format: TextureFormat, sizes: &[(usize, usize)]) -> Vec<Vec<u8>> {
    assert_eq!(&file[..4], b"DDS ");
    assert_eq!(u32_at(file, 4), 124);
    let flags = u32_at(file, 8);
    let (height, width) = (u32_at(file, 12) as usize, u32_at(file, 16) as usize);
    assert_eq!((width, height), sizes[0]);
    let count = u32_at(file, 28) as usize;
    assert_eq!(count, sizes.len());
    assert_eq!(flags & 0x1007, 0x1007, "CAPS, HEIGHT, WIDTH, PIXELFORMAT");
    assert_eq!(flags & 0x2_0000 != 0, count > 1, "MIPMAPCOUNT");
    assert_eq!(u32_at(file, 76), 32, "DDS_PIXELFORMAT's size");
    assert_eq!(u32_at(file, 80) & 0x4, 0x4, "DDPF_FOURCC");
    assert_eq!(&file[84..88], b"DX10");
    let (side, block_bytes) = match format {
        TextureFormat::Bc4 => (4, 8),
        TextureFormat::Bc5 | TextureFormat::Bc7 => (4, 16),
        TextureFormat::Rgba8 | TextureFormat::Rg16f => (1, 4),
        TextureFormat::Rg8 | TextureFormat::R16f => (1, 2),
        TextureFormat::R8 => (1, 1),
        TextureFormat::Rgba16f => (1, 8),
        #[allow(unreachable_patterns)]
        other => panic!("{other:?}"),
    };
    let pitch = u32_at(file, 20) as usize;
    if side == 4 {
        assert_eq!(flags & 0x8_0000, 0x8_0000, "LINEARSIZE");
        assert_eq!(pitch, width.div_ceil(4) * height.div_ceil(4) * block_bytes, "linear size");
    } else {
        assert_eq!(flags & 0x8, 0x8, "PITCH");
        assert_eq!(pitch, width * block_bytes, "pitch");
    }
    let caps = u32_at(file, 108);
    assert_eq!(caps & 0x1000, 0x1000, "DDSCAPS_TEXTURE");
    assert_eq!(caps & 0x40_0008 == 0x40_0008, count > 1, "COMPLEX | MIPMAP");
    let dxgi = u32_at(file, 128);
    let want = match format {
        TextureFormat::Bc4 => 80,
        TextureFormat::Bc5 => 83,
        TextureFormat::Bc7 => 98,
        TextureFormat::Rgba8 => 28,
        TextureFormat::Rg8 => 49,
        TextureFormat::R8 => 61,
        TextureFormat::Rgba16f => 10,
        TextureFormat::Rg16f => 34,
        TextureFormat::R16f => 54,
        #[allow(unreachable_patterns)]
        other => panic!("{other:?}"),
    };
    assert_eq!(dxgi, want, "DXGI_FORMAT");
    assert_eq!((u32_at(file, 132), u32_at(file, 140)), (3, 1), "a 2D texture, an array of one");
    let mut at = 148;
    let mut out = Vec::new();
    for &(w, h) in sizes {
        let length = w.div_ceil(side) * h.div_ceil(side) * block_bytes;
        out.push(file[at..at + length].to_vec());
        at += length;
    }
    assert_eq!(at, file.len(), "the levels end the file");
    out
}

// ------------------------------------------------------------------ tests

fn ktx2_of(chain: Chain<'_>, compression: Compression) -> Vec<u8> {
    let mut out = Vec::new();
    write_chain(&mut out, chain, Container::Ktx2, compression).unwrap();
    out
}

fn dds_of(chain: Chain<'_>, compression: Compression) -> Vec<u8> {
    let mut out = Vec::new();
    write_chain(&mut out, chain, Container::Dds, compression).unwrap();
    out
}

/// The bytes each uncompressed layout must hold for a level of normals.
fn expected_normal_bytes(level: &MipLevel<[f32; 3]>, layout: Uncompressed) -> Vec<u8> {
    level
        .texels
        .iter()
        .flat_map(|n| match layout {
            Uncompressed::Rgba8 => vec![byte(n[0]), byte(n[1]), byte(n[2]), 255],
            Uncompressed::Rg8 => vec![byte(n[0]), byte(n[1])],
            Uncompressed::Rgba16f => [half(n[0]), half(n[1]), half(n[2]), half(1.0)].concat(),
            Uncompressed::Rg16f => [half(n[0]), half(n[1])].concat(),
            #[allow(unreachable_patterns)]
            other => panic!("{other:?}"),
        })
        .collect()
}

#[test]
fn ktx2_of_normals_in_every_layout_reads_back() {
    let chain = normals_chain(300, 7);
    let sizes = level_sizes(300, 7);
    assert_eq!(sizes.len(), 9);
    for layout in [Uncompressed::Rgba8, Uncompressed::Rg8, Uncompressed::Rgba16f, Uncompressed::Rg16f] {
        let compression = Compression::None(layout);
        let file = ktx2_of(Chain::Normals(&chain), compression);
        let format = compression.format(&Chain::Normals(&chain)).unwrap();
        let levels = check_ktx2(&file, format, &sizes);
        for (k, (bytes, level)) in levels.iter().zip(&chain).enumerate() {
            assert_eq!(bytes, &expected_normal_bytes(level, layout), "level {k} of {layout}");
        }
        // The DDS holds the same level bytes.
        assert_eq!(read_dds(&dds_of(Chain::Normals(&chain), compression), format, &sizes), levels, "{layout}");
    }
}

/// Normals with an alpha of heights: RGBA8 and RGBA16F hold it in their
/// fourth channel, read back from the KTX2 (and the DDS) byte for byte;
/// formats without an alpha refuse it.
#[test]
fn an_alpha_goes_into_rgba8_and_rgba16f_at_every_level() {
    let (w, h) = (300, 7);
    let (chain, alpha) = (normals_chain(w, h), heights_chain(w, h));
    let sizes = level_sizes(w, h);
    for layout in [Uncompressed::Rgba8, Uncompressed::Rgba16f] {
        let compression = Compression::None(layout);
        let with_alpha = Chain::NormalsAlpha(&chain, &alpha);
        let file = ktx2_of(with_alpha, compression);
        let format = compression.format(&with_alpha).unwrap();
        let levels = check_ktx2(&file, format, &sizes);
        for (k, (bytes, (level, a))) in levels.iter().zip(chain.iter().zip(&alpha)).enumerate() {
            let mut want = expected_normal_bytes(level, layout);
            for (t, texel) in want.chunks_exact_mut(if layout == Uncompressed::Rgba8 { 4 } else { 8 }).enumerate() {
                match layout {
                    Uncompressed::Rgba8 => texel[3] = alpha_byte(a.texels[t]),
                    _ => texel[6..].copy_from_slice(&half(a.texels[t])),
                }
            }
            assert_eq!(bytes, &want, "level {k} of {layout}");
        }
        assert_eq!(read_dds(&dds_of(with_alpha, compression), format, &sizes), levels, "{layout}");
    }
    let bad = |chain: Chain<'_>, compression: Compression| {
        let mut out = Vec::new();
        let err = write_chain(&mut out, chain, Container::Ktx2, compression).unwrap_err();
        assert!(out.is_empty(), "nothing written before the error");
        err
    };
    for compression in [Compression::Bc5, Compression::None(Uncompressed::Rg8), Compression::None(Uncompressed::Rg16f)]
    {
        let err = bad(Chain::NormalsAlpha(&chain, &alpha), compression);
        assert!(matches!(&err, Error::InvalidOption(m) if m.contains("has no alpha")), "{compression}: {err}");
    }
    let err = bad(Chain::NormalsAlpha(&chain, &alpha[..3]), Compression::None(Uncompressed::Rgba8));
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("alpha's levels")), "{err}");
    let mut nan = alpha.clone();
    nan[1].texels[4] = f32::NAN;
    let err = bad(Chain::NormalsAlpha(&chain, &nan), Compression::None(Uncompressed::Rgba8));
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("of level 1")), "{err}");
}

#[test]
fn bc5_levels_decode_within_the_block_bound() {
    for (w, h) in [(300, 7), (64, 40), (2, 2), (1, 1), (5, 3)] {
        let chain = normals_chain(w, h);
        let sizes = level_sizes(w, h);
        let ktx2 = ktx2_of(Chain::Normals(&chain), Compression::Bc5);
        let levels = check_ktx2(&ktx2, TextureFormat::Bc5, &sizes);
        assert_eq!(read_dds(&dds_of(Chain::Normals(&chain), Compression::Bc5), TextureFormat::Bc5, &sizes), levels);
        for (k, (bytes, level)) in levels.iter().zip(&chain).enumerate() {
            let decoded = decode_bc_level(bytes, (level.width, level.height), 2);
            let source = |t: usize| vec![code(level.texels[t][0]), code(level.texels[t][1])];
            check_bc(&decoded, (level.width, level.height), source, &format!("{w} × {h} level {k}"));
        }
    }
}

#[test]
fn bc5_from_floats_beats_bc5_from_rounded_normals() {
    // The promise of encoding from the floats: a smaller error than the
    // same encoder given the normals rounded to 8 bits first (as an
    // 8-bit normal map would give them), on smooth normals (the bumps
    // spread eight times wider), measured against the floats.
    let smooth = bumps(128, 128, 8.0);
    let rounded: Vec<[f32; 3]> = smooth.iter().map(|n| n.map(|c| (f64::from(byte(c)) / 127.5 - 1.0) as f32)).collect();
    let error = |normals: &[[f32; 3]]| {
        let level = [MipLevel { width: 128, height: 128, texels: normals.to_vec() }];
        let bytes = &encode_chain(Chain::Normals(&level), Compression::Bc5).unwrap().levels[0];
        let decoded = decode_bc_level(bytes, (128, 128), 2);
        smooth.iter().zip(&decoded).map(|(n, d)| (0..2).map(|c| (code(n[c]) - d[c]).powi(2)).sum::<f64>()).sum::<f64>()
    };
    let (from_floats, from_bytes) = (error(&smooth), error(&rounded));
    assert!(
        from_floats < 0.8 * from_bytes,
        "BC5 squared error from floats {from_floats:.1}, from 8-bit normals {from_bytes:.1}"
    );
}

#[test]
fn one_channel_chains_in_bc4_r8_r16f() {
    let chain = values_chain(300, 7);
    let sizes = level_sizes(300, 7);
    for compression in [Compression::Bc4, Compression::None(Uncompressed::R8), Compression::None(Uncompressed::R16f)] {
        let format = compression.format(&Chain::Values(&chain)).unwrap();
        let levels = check_ktx2(&ktx2_of(Chain::Values(&chain), compression), format, &sizes);
        assert_eq!(read_dds(&dds_of(Chain::Values(&chain), compression), format, &sizes), levels);
        for (k, (bytes, level)) in levels.iter().zip(&chain).enumerate() {
            match format {
                TextureFormat::Bc4 => {
                    let decoded = decode_bc_level(bytes, (level.width, level.height), 1);
                    let source = |t: usize| vec![f64::from(level.texels[t].clamp(0.0, 1.0)) * 255.0];
                    check_bc(&decoded, (level.width, level.height), source, &format!("BC4 level {k}"));
                }
                TextureFormat::R8 => {
                    let want: Vec<u8> = level.texels.iter().map(|v| (f64::from(*v) * 255.0).round() as u8).collect();
                    assert_eq!(bytes, &want, "R8 level {k}");
                }
                _ => {
                    let want: Vec<u8> = level.texels.iter().flat_map(|v| half(*v)).collect();
                    assert_eq!(bytes, &want, "R16F level {k}");
                }
            }
        }
    }
}

#[cfg(feature = "bc7")]
#[test]
fn bc7_levels_have_their_block_counts() {
    let chain = normals_chain(300, 7);
    let sizes = level_sizes(300, 7);
    let levels = check_ktx2(&ktx2_of(Chain::Normals(&chain), Compression::Bc7), TextureFormat::Bc7, &sizes);
    assert_eq!(read_dds(&dds_of(Chain::Normals(&chain), Compression::Bc7), TextureFormat::Bc7, &sizes), levels);
}

#[test]
fn block_counts_of_odd_and_tiny_chains() {
    // 300 × 7: 9 levels; blocks across × down at each.
    let chain = normals_chain(300, 7);
    let encoded = encode_chain(Chain::Normals(&chain), Compression::Bc5).unwrap();
    let blocks: Vec<usize> = encoded.levels.iter().map(|l| l.len() / 16).collect();
    assert_eq!(blocks, [75 * 2, 38, 19, 10, 5, 3, 1, 1, 1]);
    // 2 × 2 and 1 × 1: one block each level.
    for (w, h, levels) in [(2, 2, 2), (1, 1, 1)] {
        let chain = normals_chain(w, h);
        let EncodedChain { sizes, levels: bytes, .. } = encode_chain(Chain::Normals(&chain), Compression::Bc5).unwrap();
        assert_eq!(sizes.len(), levels);
        assert!(bytes.iter().all(|l| l.len() == 16));
        let values = values_chain(w, h);
        let bc4 = encode_chain(Chain::Values(&values), Compression::Bc4).unwrap();
        assert!(bc4.levels.iter().all(|l| l.len() == 8));
    }
}

#[test]
fn the_first_levels_of_a_chain_are_a_chain() {
    let chain = normals_chain(64, 40);
    let file = ktx2_of(Chain::Normals(&chain[..3]), Compression::Bc5);
    check_ktx2(&file, TextureFormat::Bc5, &level_sizes(64, 40)[..3]);
}

#[test]
fn bad_combinations_are_named_errors() {
    let normals = normals_chain(8, 8);
    let values = values_chain(8, 8);
    let bad = |chain: Chain<'_>, compression: Compression| {
        let mut out = Vec::new();
        let err = write_chain(&mut out, chain, Container::Ktx2, compression).unwrap_err();
        assert!(out.is_empty(), "nothing written before the error");
        err
    };
    for compression in [Compression::Bc4, Compression::None(Uncompressed::R8), Compression::None(Uncompressed::R16f)] {
        let err = bad(Chain::Normals(&normals), compression);
        assert!(matches!(&err, Error::InvalidOption(m) if m.contains("one channel")), "{compression}: {err}");
    }
    for compression in [
        Compression::Bc5,
        Compression::Bc7,
        Compression::None(Uncompressed::Rg8),
        Compression::None(Uncompressed::Rgba8),
        Compression::None(Uncompressed::Rg16f),
        Compression::None(Uncompressed::Rgba16f),
    ] {
        let err = bad(Chain::Values(&values), compression);
        assert!(matches!(&err, Error::InvalidOption(m) if m.contains("bc4, r8 or r16f")), "{compression}: {err}");
    }
    // Not a chain: no levels, a level of the wrong size, texels missing.
    let err = bad(Chain::Normals(&[]), Compression::Bc5);
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("no levels")), "{err}");
    let mut wrong = normals.clone();
    wrong[1] = MipLevel { width: 3, height: 4, texels: vec![[0.0, 0.0, 1.0]; 12] };
    let err = bad(Chain::Normals(&wrong), Compression::Bc5);
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("level 1 is 3 × 4")), "{err}");
    let mut short = normals.clone();
    short[0].texels.pop();
    assert!(matches!(bad(Chain::Normals(&short), Compression::Bc5), Error::BufferSize { expected: 64, actual: 63 }));
    let mut long = normals.clone();
    long.push(MipLevel { width: 1, height: 1, texels: vec![[0.0, 0.0, 1.0]] });
    let err = bad(Chain::Normals(&long), Compression::Bc5);
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("has 4 levels, not 5")), "{err}");
    // Non-finite texels.
    let mut nan = normals.clone();
    nan[2].texels[1][1] = f32::NAN;
    assert!(matches!(bad(Chain::Normals(&nan), Compression::Bc5), Error::NonFiniteNormal { x: 1, y: 0 }));
    let mut inf = values.clone();
    inf[0].texels[9] = f32::INFINITY;
    let err = bad(Chain::Values(&inf), Compression::Bc4);
    assert!(matches!(&err, Error::InvalidOption(m) if m.contains("(x 1, y 1) of level 0")), "{err}");
    // Names.
    assert!(matches!("bc1".parse::<Compression>(), Err(Error::InvalidOption(_))));
    assert!(matches!("ktx".parse::<Container>(), Err(Error::InvalidOption(_))));
    assert!(matches!(Container::from_path("a.png".as_ref()), Err(Error::Unsupported(_))));
}

#[test]
fn a_file_by_path_appears_whole_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let chain = normals_chain(16, 8);
    let path = dir.path().join("n.ktx2");
    write_chain_file(&path, Chain::Normals(&chain), Compression::Bc5).unwrap();
    check_ktx2(&std::fs::read(&path).unwrap(), TextureFormat::Bc5, &level_sizes(16, 8));
    let path = dir.path().join("n.dds");
    write_chain_file(&path, Chain::Normals(&chain), Compression::None(Uncompressed::Rg8)).unwrap();
    read_dds(&std::fs::read(&path).unwrap(), TextureFormat::Rg8, &level_sizes(16, 8));
    // A bad combination leaves no file.
    let path = dir.path().join("bad.dds");
    assert!(write_chain_file(&path, Chain::Normals(&chain), Compression::Bc4).is_err());
    assert!(!path.exists());
}

// ------------------------------------------------------------------ Pillow

/// The interpreter with Pillow: `NORMALFIT_PYTHON`, else `python3`.
fn python() -> String {
    std::env::var("NORMALFIT_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// A DDS file of one level, cut from a chain's file: the header with that
/// level's size, one level, its pitch or linear size; then its bytes.
fn single_level_dds(file: &[u8], format: TextureFormat, sizes: &[(usize, usize)], k: usize) -> Vec<u8> {
    let levels = read_dds(file, format, sizes);
    let (w, h) = sizes[k];
    let mut out = file[..148].to_vec();
    let put = |out: &mut Vec<u8>, at: usize, v: u32| out[at..at + 4].copy_from_slice(&v.to_le_bytes());
    put(&mut out, 8, u32_at(file, 8) & !0x2_0000);
    put(&mut out, 12, h as u32);
    put(&mut out, 16, w as u32);
    let pitch = if format == TextureFormat::Rgba8 { 4 * w } else { levels[k].len() };
    put(&mut out, 20, pitch as u32);
    put(&mut out, 28, 1);
    put(&mut out, 108, 0x1000);
    out.extend_from_slice(&levels[k]);
    out
}

/// Pillow's decoding of each DDS file: RGBA bytes, or a panic with
/// Python's message.
fn pillow_decode(files: &[std::path::PathBuf]) -> Vec<Vec<u8>> {
    let script = r#"
import sys
from PIL import Image
for path in sys.argv[1:]:
    with Image.open(path) as im:
        im.convert("RGBA").save(path + ".rgba.png")
"#;
    let out = std::process::Command::new(python())
        .arg("-c")
        .arg(script)
        .args(files)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e} (set NORMALFIT_PYTHON)", python()));
    assert!(out.status.success(), "Pillow failed: {}", String::from_utf8_lossy(&out.stderr));
    files
        .iter()
        .map(|f| {
            let png = std::fs::read(format!("{}.rgba.png", f.display())).unwrap();
            let decoder = png::Decoder::new(std::io::Cursor::new(png));
            let mut reader = decoder.read_info().unwrap();
            let mut buf = vec![0; reader.output_buffer_size().unwrap()];
            let info = reader.next_frame(&mut buf).unwrap();
            buf.truncate(info.buffer_size());
            buf
        })
        .collect()
}

#[test]
#[ignore = "needs python3 with Pillow (NORMALFIT_PYTHON names the interpreter; CI installs it)"]
fn pillow_decodes_every_level() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37, 21);
    // Bumps three times wider than elsewhere: BC7's error, which has no
    // bound in closed form, is checked against a limit that holds for
    // smooth normals.
    let chain = average_chain(&bumps(w, h, 3.0), (w, h)).unwrap();
    let values = mean_lengths(&bumps(w, h, 3.0), (w, h)).unwrap();
    let alpha = heights_chain(w, h);
    let sizes = level_sizes(w, h);
    let rgba8 = Compression::None(Uncompressed::Rgba8);
    // Each case: its compression, format and file, and whether its alpha
    // holds `alpha` (else it is opaque).
    let mut cases: Vec<(Compression, TextureFormat, Vec<u8>, bool)> = vec![
        (Compression::Bc5, TextureFormat::Bc5, dds_of(Chain::Normals(&chain), Compression::Bc5), false),
        (Compression::Bc4, TextureFormat::Bc4, dds_of(Chain::Values(&values), Compression::Bc4), false),
        (rgba8, TextureFormat::Rgba8, dds_of(Chain::Normals(&chain), rgba8), false),
        (rgba8, TextureFormat::Rgba8, dds_of(Chain::NormalsAlpha(&chain, &alpha), rgba8), true),
    ];
    if cfg!(feature = "bc7") {
        cases.push((Compression::Bc7, TextureFormat::Bc7, dds_of(Chain::Normals(&chain), Compression::Bc7), false));
        let with_alpha = dds_of(Chain::NormalsAlpha(&chain, &alpha), Compression::Bc7);
        cases.push((Compression::Bc7, TextureFormat::Bc7, with_alpha, true));
    }
    let mut files = Vec::new();
    for (case, (compression, format, file, _)) in cases.iter().enumerate() {
        for k in 0..sizes.len() {
            let path = dir.path().join(format!("{compression}-{case}-{k}.dds"));
            std::fs::write(&path, single_level_dds(file, *format, &sizes, k)).unwrap();
            files.push(path);
        }
    }
    let decoded = pillow_decode(&files);
    let mut next = decoded.iter();
    for (compression, _, _, with_alpha) in &cases {
        for (k, level) in chain.iter().enumerate() {
            let rgba = next.next().unwrap();
            let (lw, lh) = (level.width, level.height);
            assert_eq!(rgba.len(), lw * lh * 4, "{compression} level {k}");
            let alpha_in = if *with_alpha { " with an alpha" } else { "" };
            let what = format!("{compression}{alpha_in} level {k} ({lw} × {lh}) by Pillow");
            let want_alpha = |t: usize| if *with_alpha { alpha_byte(alpha[k].texels[t]) } else { 255 };
            match compression {
                Compression::Bc5 => {
                    let got: Vec<Vec<f64>> =
                        rgba.chunks_exact(4).map(|p| vec![f64::from(p[0]), f64::from(p[1])]).collect();
                    // Pillow rounds the interpolated values to bytes: half a code more.
                    let source = |t: usize| vec![code(level.texels[t][0]), code(level.texels[t][1])];
                    check_bc_rounded(&got, (lw, lh), source, &what);
                }
                Compression::Bc4 => {
                    let got: Vec<Vec<f64>> = rgba.chunks_exact(4).map(|p| vec![f64::from(p[0])]).collect();
                    let level = &values[k];
                    let source = |t: usize| vec![f64::from(level.texels[t]) * 255.0];
                    check_bc_rounded(&got, (lw, lh), source, &what);
                }
                Compression::None(_) => {
                    let want: Vec<u8> = (level.texels.iter().enumerate())
                        .flat_map(|(t, n)| [byte(n[0]), byte(n[1]), byte(n[2]), want_alpha(t)])
                        .collect();
                    assert_eq!(rgba, &want, "{what}");
                }
                _ => {
                    // BC7: no bound in closed form; the angle of the
                    // decoded normal against the float one, within what
                    // BC7 gives smooth normals (a level read from the
                    // wrong place, or channels swapped, is tens of
                    // degrees off).
                    let mut worst: f64 = 0.0;
                    let mut sum = 0.0;
                    for (p, n) in rgba.chunks_exact(4).zip(&level.texels) {
                        let m: Vec<f64> = p[..3].iter().map(|&c| f64::from(c) / 127.5 - 1.0).collect();
                        let len = m.iter().map(|c| c * c).sum::<f64>().sqrt();
                        let dot = (0..3).map(|c| f64::from(n[c]) * m[c]).sum::<f64>() / len;
                        let angle = dot.clamp(-1.0, 1.0).acos().to_degrees();
                        worst = worst.max(angle);
                        sum += angle;
                    }
                    let mean = sum / level.texels.len() as f64;
                    // With an alpha, BC7's modes give the colours fewer
                    // bits (modes 4 to 7; no partitions of three): on
                    // small levels of varied normals, twice the error.
                    let (mean_limit, worst_limit) = if *with_alpha { (8.0, 20.0) } else { (4.0, 10.0) };
                    assert!(mean < mean_limit && worst < worst_limit, "{what}: mean {mean:.3}°, worst {worst:.3}°");
                    // The alpha: opaque, or the heights: on average within
                    // half a step of BC7's coarsest alpha indices (four
                    // steps: a sixth of the block's span) and 2 codes, and
                    // each texel within half its block's span and 3 codes
                    // (BC7's alpha has no bound in closed form: modes 6
                    // and 7 share their indices with the colours, and on
                    // the tiny last levels of varied normals the encoder
                    // favours them). An alpha from another level, or
                    // none, is further off.
                    let block = |t: usize| (t % lw / 4, t / lw / 4);
                    let span = |t: usize| {
                        let (lo, hi) = (0..lw * lh)
                            .filter(|&u| block(u) == block(t))
                            .map(|u| f64::from(want_alpha(u)))
                            .fold((f64::MAX, f64::MIN), |(lo, hi), a| (lo.min(a), hi.max(a)));
                        hi - lo
                    };
                    let errors: Vec<f64> = (rgba.chunks_exact(4).enumerate())
                        .map(|(t, p)| (f64::from(p[3]) - f64::from(want_alpha(t))).abs())
                        .collect();
                    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
                    let worst = errors.iter().fold(0.0f64, |a, &b| a.max(b));
                    match with_alpha {
                        true => {
                            let half_steps = (0..lw * lh).map(|t| span(t) / 6.0).sum::<f64>() / (lw * lh) as f64;
                            assert!(
                                mean <= half_steps + 2.0,
                                "{what}: alpha off by {mean:.2} on average ({half_steps:.2})"
                            );
                            for (t, e) in errors.iter().enumerate() {
                                let bound = span(t) / 2.0 + 3.0;
                                assert!(*e <= bound, "{what}: alpha of texel {t} off by {e}, bound {bound:.1}");
                            }
                        }
                        // Opaque: BC7's mode 6 stores 255 as 254 where its
                        // endpoints' shared bit is 0.
                        false => assert!(worst <= 1.0, "{what}: an opaque alpha, {worst} off"),
                    }
                }
            }
        }
    }
}

/// [`check_bc`] for decoders that round to bytes: half a code more.
fn check_bc_rounded(decoded: &[Vec<f64>], size: (usize, usize), source: impl Fn(usize) -> Vec<f64>, what: &str) {
    // Widen each source value's bound by moving the decoded value half a
    // code towards it.
    let adjusted: Vec<Vec<f64>> = decoded
        .iter()
        .enumerate()
        .map(|(t, d)| d.iter().zip(source(t)).map(|(&g, w)| g + (w - g).clamp(-0.5, 0.5)).collect())
        .collect();
    check_bc(&adjusted, size, source, what);
}
