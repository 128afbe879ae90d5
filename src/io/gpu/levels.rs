//! A mip chain's shape, as the GPU files hold it: its levels
//! ([`MipLevel`]) and their sizes ([`level_sizes`]). [`crate::mips`] makes
//! the chains; the writers here store them.

/// One level of a chain: its size and its texels, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct MipLevel<T> {
    /// Texels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height` texels.
    pub texels: Vec<T>,
}

/// The sizes of a chain's levels, the finest first: each side
/// max(1, ⌊n / 2⌋) of the level before, down to 1 × 1 (Direct3D's and
/// Vulkan's count: 1 + ⌊log₂ max(w, h)⌋ levels).
///
/// ```
/// use normalfit::mips::level_sizes;
/// assert_eq!(level_sizes(300, 7), [(300, 7), (150, 3), (75, 1), (37, 1), (18, 1), (9, 1), (4, 1), (2, 1), (1, 1)]);
/// ```
#[must_use]
pub fn level_sizes(width: usize, height: usize) -> Vec<(usize, usize)> {
    let mut sizes = vec![(width, height)];
    let (mut w, mut h) = (width, height);
    while w > 1 || h > 1 {
        (w, h) = ((w / 2).max(1), (h / 2).max(1));
        sizes.push((w, h));
    }
    sizes
}
