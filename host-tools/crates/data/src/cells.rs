//! Column cell storage: every cell of a column in one string buffer plus end offsets (one allocation per
//! column instead of one per cell).

use std::ops::Index;

/// The text cells of one column.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Cells {
    buf: String,
    /// End offset of each cell in `buf`; cell i is `buf[ends[i-1]..ends[i]]` (start 0 for i = 0).
    ends: Vec<usize>,
}

impl Cells {
    pub(crate) fn with_capacity(cells: usize, bytes: usize) -> Self {
        Cells {
            buf: String::with_capacity(bytes),
            ends: Vec::with_capacity(cells),
        }
    }

    pub(crate) fn push(&mut self, cell: &str) {
        self.buf.push_str(cell);
        self.ends.push(self.buf.len());
    }

    pub(crate) fn len(&self) -> usize {
        self.ends.len()
    }

    pub(crate) fn get(&self, i: usize) -> &str {
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        &self.buf[start..self.ends[i]]
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
