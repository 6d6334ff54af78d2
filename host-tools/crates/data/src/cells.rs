//! Column cell storage: every cell of a column in one string buffer plus 32-bit end offsets (one
//! allocation per column instead of one per cell; a column holds at most 4 GiB of text).

use std::ops::Index;

/// The text cells of one column.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Cells {
    buf: String,
    /// End offset of each cell in `buf`; cell i is `buf[ends[i-1]..ends[i]]` (start 0 for i = 0).
    ends: Vec<u32>,
}

impl Cells {
    /// Whether a cell of `len` bytes still fits (the text of a column stays below 4 GiB).
    pub(crate) fn fits(&self, len: usize) -> bool {
        self.buf.len() + len <= u32::MAX as usize
    }

    /// Appends a cell. Panics when the column's text would exceed 4 GiB (check [`Cells::fits`]).
    pub(crate) fn push(&mut self, cell: &str) {
        assert!(self.fits(cell.len()), "column text above 4 GiB");
        self.buf.push_str(cell);
        self.ends.push(self.buf.len() as u32);
    }

    /// Bytes of text held.
    pub(crate) fn bytes(&self) -> usize {
        self.buf.len()
    }

    pub(crate) fn reserve(&mut self, cells: usize, bytes: usize) {
        self.ends.reserve(cells);
        self.buf.reserve(bytes);
    }

    pub(crate) fn shrink_to_fit(&mut self) {
        self.ends.shrink_to_fit();
        self.buf.shrink_to_fit();
    }

    pub(crate) fn len(&self) -> usize {
        self.ends.len()
    }

    pub(crate) fn get(&self, i: usize) -> &str {
        let start = if i == 0 { 0 } else { self.ends[i - 1] as usize };
        &self.buf[start..self.ends[i] as usize]
    }

    pub(crate) fn iter(&self) -> impl Iterator<Item = &str> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }
}

impl Index<usize> for Cells {
    type Output = str;
    fn index(&self, i: usize) -> &str {
        self.get(i)
    }
}

impl<S: AsRef<str>> FromIterator<S> for Cells {
    fn from_iter<I: IntoIterator<Item = S>>(iter: I) -> Self {
        let mut c = Cells::default();
        for s in iter {
            c.push(s.as_ref());
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_keep_empty_and_unicode_cells() {
        let c: Cells = ["a", "", "µm, x", ""].into_iter().collect();
        assert_eq!(c.len(), 4);
        assert_eq!(c.iter().collect::<Vec<_>>(), vec!["a", "", "µm, x", ""]);
        assert_eq!(&c[2], "µm, x");
    }
}
