//! Detail at several scales: patch sizes and their weights, checked once
//! here for every front end (docs/detail.md).

use crate::error::{Error, Number};

use super::MAX_PATCH;

/// The most scales a [`Detail`] takes: each costs a fit of the image, and
/// the tools that mix scales use four to seven.
pub const MAX_SCALES: usize = 16;

/// The largest weight magnitude accepted: slopes times weights stay far
/// inside f64's range.
pub const MAX_WEIGHT: f64 = 1e6;

/// Several patch sizes fitted at once, each with a weight: the normal of
/// the weighted sum of the scales' slopes,
/// n ∝ (−Σ wₖ pₖ, −Σ wₖ qₖ, 1), where (pₖ, qₖ) = (−nx/nz, −ny/nz) are the
/// slopes of the plane fitted with patch size Nₖ (docs/detail.md gives the
/// rule and why slopes, not normals, are summed).
///
/// Sizes are odd, at least 3 and at most [`MAX_PATCH`], none twice;
/// weights finite, of magnitude at most [`MAX_WEIGHT`] (a negative weight
/// subtracts a scale); one to [`MAX_SCALES`] scales. The order given is the
/// order the slopes are added in.
///
/// ```
/// use normalfit::Detail;
/// let detail: Detail = "3:1, 9:0.5, 33:0.25".parse()?;
/// assert_eq!(detail.scales(), &[(3, 1.0), (9, 0.5), (33, 0.25)]);
/// assert_eq!(detail.largest_patch(), 33);
/// assert!(Detail::new([(4, 1.0)]).is_err());
/// # Ok::<(), normalfit::Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Detail {
    scales: Vec<(usize, f64)>,
}

impl Detail {
    /// The scales `(N, weight)`, checked.
    ///
    /// Errors: [`Error::InvalidOption`] naming the first rule broken.
    pub fn new(scales: impl IntoIterator<Item = (usize, f64)>) -> Result<Detail, Error> {
        let scales: Vec<(usize, f64)> = scales.into_iter().take(MAX_SCALES + 1).collect();
        if scales.is_empty() {
            return Err(Error::InvalidOption("detail needs at least one scale N:W".into()));
        }
        if scales.len() > MAX_SCALES {
            return Err(Error::InvalidOption(format!("detail takes at most {MAX_SCALES} scales")));
        }
        for (k, &(n, w)) in scales.iter().enumerate() {
            if n < 3 || n.is_multiple_of(2) || n > MAX_PATCH {
                return Err(Error::InvalidOption(format!(
                    "detail patch size must be odd, at least 3 and at most {MAX_PATCH}, got {n}"
                )));
            }
            if !(w.is_finite() && w.abs() <= MAX_WEIGHT) {
                return Err(Error::InvalidOption(format!(
                    "detail weight must be finite and of magnitude at most {MAX_WEIGHT:e}, got {} for size {n}",
                    Number(w)
                )));
            }
            if scales[..k].iter().any(|&(m, _)| m == n) {
                return Err(Error::InvalidOption(format!("detail gives patch size {n} twice")));
            }
        }
        Ok(Detail { scales })
    }

    /// The scales `(N, weight)`, in the order given.
    #[must_use]
    pub fn scales(&self) -> &[(usize, f64)] {
        &self.scales
    }

    /// The largest N: the patch whose reach (N / 2 texels) sets the halo
    /// of a window or a band.
    #[must_use]
    pub fn largest_patch(&self) -> usize {
        self.scales.iter().map(|s| s.0).max().unwrap_or(3)
    }

    /// The single size whose plain fit this is, bit for bit: one scale of
    /// weight 1 (n ∝ (−p, −q, 1) is then the fitted plane's own normal).
    #[must_use]
    pub fn as_single(&self) -> Option<usize> {
        match self.scales[..] {
            [(n, 1.0)] => Some(n),
            _ => None,
        }
    }
}

impl std::fmt::Display for Detail {
    /// As front ends spell it: `3:1,9:0.5`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (k, &(n, w)) in self.scales.iter().enumerate() {
            let sep = if k == 0 { "" } else { "," };
            write!(f, "{sep}{n}:{}", Number(w))?;
        }
        Ok(())
    }
}

impl std::str::FromStr for Detail {
    type Err = Error;

    /// `N:W,N:W,…` (spaces around items ignored); `N` alone is weight 1.
    fn from_str(s: &str) -> Result<Detail, Error> {
        let mut scales = Vec::new();
        for item in s.split(',') {
            let item = item.trim();
            let (n, w) = item.split_once(':').unwrap_or((item, "1"));
            let n: usize = n.trim().parse().map_err(|_| {
                Error::InvalidOption(format!("detail scale '{item}' is not N:W (an odd size and a weight)"))
            })?;
            let w: f64 = w.trim().parse().map_err(|_| {
                Error::InvalidOption(format!("detail scale '{item}' is not N:W (an odd size and a weight)"))
            })?;
            scales.push((n, w));
        }
        Detail::new(scales)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_parse_print_and_keep_their_order() {
        let d: Detail = " 9:0.5,3:1 ,33".parse().unwrap();
        assert_eq!(d.scales(), &[(9, 0.5), (3, 1.0), (33, 1.0)]);
        assert_eq!(d.to_string(), "9:0.5,3:1,33:1");
        assert_eq!(d.to_string().parse::<Detail>().unwrap(), d);
        assert_eq!((d.largest_patch(), d.as_single()), (33, None));
        assert_eq!("5:1".parse::<Detail>().unwrap().as_single(), Some(5));
        assert_eq!("5:2".parse::<Detail>().unwrap().as_single(), None);
        assert!("3:-0.5,5:1e6".parse::<Detail>().is_ok(), "negative weights subtract a scale");
    }

    #[test]
    fn every_rule_is_refused_in_one_line() {
        let refused = |s: &str| s.parse::<Detail>().unwrap_err().to_string();
        assert_eq!(
            refused("4:1"),
            format!("invalid option: detail patch size must be odd, at least 3 and at most {MAX_PATCH}, got 4")
        );
        assert!(refused("1:1").contains("got 1"));
        assert!(refused(&format!("{}:1", MAX_PATCH + 2)).contains("at most"));
        assert_eq!(refused("3:1,9:2,3:0.5"), "invalid option: detail gives patch size 3 twice");
        assert!(refused("3:nan").contains("finite"), "{}", refused("3:nan"));
        assert!(refused("3:inf").contains("finite"));
        assert!(refused("3:2e6").contains("magnitude"));
        assert!(refused("3:x").contains("is not N:W"));
        assert!(refused("").contains("is not N:W"));
        assert!(refused("3:1,,5:1").contains("is not N:W"));
        let many: Vec<String> = (0..=MAX_SCALES).map(|k| format!("{}:1", 3 + 2 * k)).collect();
        assert!(refused(&many.join(",")).contains(&format!("at most {MAX_SCALES} scales")));
        assert!(Detail::new([]).is_err());
    }
}
