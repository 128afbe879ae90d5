//! The fast fit against the slow reference, and the properties the
//! contract promises (parallel equals serial, wrap commutes with shifts,
//! flat in → flat out, known answers).

mod common;

use common::reference;
use normalfit::{normals, normals_into, Border, Borders, Convention, Fit, Options, Strength};
use proptest::prelude::*;

const BORDERS: [Border; 3] = [Border::Wrap, Border::Clamp, Border::Mirror];

fn max_error(fast: &[[f32; 3]], slow: &[[f64; 3]]) -> (f64, usize) {
    let mut worst = (0.0, 0);
    for (k, (f, s)) in fast.iter().zip(slow).enumerate() {
        for c in 0..3 {
            let e = (f[c] as f64 - s[c]).abs();
            if e > worst.0 {
                worst = (e, k);
            }
        }
    }
    worst
}

fn options_strategy() -> impl Strategy<Value = Options> {
    (
        (1usize..=31).prop_map(|r| 2 * r + 1),
        prop_oneof![Just(Fit::Orthogonal), Just(Fit::Vertical)],
        (0usize..3, 0usize..3),
        prop_oneof![Just(Convention::OpenGl), Just(Convention::DirectX)],
        prop_oneof![
            (0.05f64..50.0).prop_map(Strength::Scale),
            (0.001f64..0.3).prop_map(Strength::Relief)
        ],
        any::<bool>(),
    )
        .prop_map(|(n, fit, (bx, by), conv, strength, invert)| {
            Options::new()
                .with_patch(n)
                .with_fit(fit)
                .with_borders(Borders { x: BORDERS[bx], y: BORDERS[by] })
                .with_convention(conv)
                .with_strength(strength)
                .with_invert(invert)
        })
}

fn image_strategy() -> impl Strategy<Value = (usize, usize, Vec<f32>)> {
    prop_oneof![
        Just((1usize, 1usize)),
        (1usize..=40).prop_map(|w| (w, 1)),
        (1usize..=40).prop_map(|h| (1, h)),
        (2usize..=40, 2usize..=40),
    ]
    .prop_flat_map(|(w, h)| (Just(w), Just(h), prop::collection::vec(0.0f32..1.0, w * h)))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn fast_fit_matches_the_reference((w, h, heights) in image_strategy(), opts in options_strategy()) {
        let fast = normals(&heights, w, h, &opts).unwrap();
        let slow = reference::normal_map(&heights, w, h, &opts);
        let (err, at) = max_error(&fast, &slow);
        prop_assert!(err < 1e-5, "error {err:e} at texel {at} of {w}x{h}: fast {:?} slow {:?}", fast[at], slow[at]);
    }

    #[test]
    fn heights_far_from_zero_keep_their_detail(
        (w, h, detail) in image_strategy(),
        offset in -1000.0f32..1000.0,
        opts in options_strategy(),
    ) {
        // Detail of a few hundredths on top of an offset up to ±1000.
        let heights: Vec<f32> = detail.iter().map(|d| offset + 0.05 * d).collect();
        let fast = normals(&heights, w, h, &opts).unwrap();
        let slow = reference::normal_map(&heights, w, h, &opts);
        let (err, at) = max_error(&fast, &slow);
        prop_assert!(err < 1e-5, "error {err:e} at texel {at}");
    }
}
