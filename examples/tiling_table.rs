//! Prints the tiling scores of the shared real textures (when
//! `../shared/data` is there) and of the generated cases: the figures
//! behind the default threshold in `normalfit::tiling`'s docs.
//!
//! `cargo run --release --example tiling_table`

#[path = "../tests/tiling_support/mod.rs"]
mod support;

use normalfit::tiling::{TilingOptions, check};

fn main() {
    let opts = TilingOptions::default();
    let mut cases = Vec::new();
    match support::real_cases() {
        Some(real) => cases.extend(real),
        None => println!("(../shared/data absent: real textures skipped)"),
    }
    cases.extend(support::spec_cases());
    for n in [64, 256] {
        cases.extend(support::generated_cases(n));
    }
    for n in [256, 512] {
        cases.extend(support::structured_cases(n));
    }
    cases.extend(support::hard_photo_cases());
    println!("threshold {}", opts.threshold);
    println!("| case | kind | x score | y score | expected x/y | verdict x/y |");
    println!("|---|---|---|---|---|---|");
    let mut wrong = 0;
    for c in &cases {
        let r = check(&c.image.refs(), c.image.width, c.image.height, &opts).unwrap();
        let ok = (r.x.seamless, r.y.seamless) == c.expect && r.kind == c.kind;
        wrong += usize::from(!ok);
        let yn = |b: bool| if b { "tiles" } else { "seam" };
        println!(
            "| {} | {:?} | {:.2} | {:.2} | {}/{} | {}/{}{} |",
            c.name,
            r.kind,
            r.x.score,
            r.y.score,
            yn(c.expect.0),
            yn(c.expect.1),
            yn(r.x.seamless),
            yn(r.y.seamless),
            if ok { "" } else { " WRONG" }
        );
    }
    println!("{wrong} wrong of {}", cases.len());
}
