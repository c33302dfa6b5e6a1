//! Data parallelism with rayon under the `host` feature, the same iterator calls run
//! sequentially without it (same results: every parallel use here collects in order).

#[cfg(feature = "host")]
pub(crate) use rayon::prelude::*;

/// Sequential stand-ins for rayon's `into_par_iter`, `par_iter`, `par_chunks`.
#[cfg(not(feature = "host"))]
pub(crate) trait Sequential: IntoIterator + Sized {
    /// `self.into_iter()`.
    fn into_par_iter(self) -> Self::IntoIter {
        self.into_iter()
    }
}

#[cfg(not(feature = "host"))]
impl<T: IntoIterator> Sequential for T {}
