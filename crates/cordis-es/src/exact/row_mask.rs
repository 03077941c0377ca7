//! Which rows of the short cost a solve leaves out (Provot's rows, [`super::provot_rows`]).

/// Rows of the short cost, frame-major: `bits[t * n + i]` (frames 0 and 1 are never rows).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct RowMask {
    n: usize,
    bits: Vec<bool>,
}

impl RowMask {
    pub(crate) fn new(frames: usize, n: usize) -> Self {
        RowMask {
            n,
            bits: vec![false; frames * n],
        }
    }

    /// Whether row (frame t, particle i) is dropped.
    #[inline]
    pub(crate) fn get(&self, t: usize, i: usize) -> bool {
        self.bits[t * self.n + i]
    }

    pub(crate) fn set(&mut self, t: usize, i: usize) {
        self.bits[t * self.n + i] = true;
    }

    pub(crate) fn count(&self) -> usize {
        self.bits.iter().filter(|&&b| b).count()
    }

    /// Adds `other`'s rows; returns whether any was new.
    pub(crate) fn absorb(&mut self, other: &RowMask) -> bool {
        let mut grew = false;
        for (a, &b) in self.bits.iter_mut().zip(&other.bits) {
            if b && !*a {
                *a = true;
                grew = true;
            }
        }
        grew
    }
}
