//! R387 paging (SPEC §7.5): the preview draws a number of blocks per page; 0 = all.

use kernel::constants::Constants;

/// Blocks per page from R387 (0 = the whole program on one page), for tools without a machine
/// setup; the daemon's preview takes [`kernel::machine::MachineSetup::preview_page_blocks`].
pub fn blocks_per_page(c: &Constants) -> u32 {
    c.preview_page_blocks()
}

/// One page: programmed blocks with `seq` in `first..end` (0-based program order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Page {
    /// 1-based page number.
    pub number: u32,
    pub first: u32,
    /// One past the last block (`u32::MAX` when the page runs to the end of the program).
    pub end: u32,
}

impl Page {
    /// Page `number` (1-based; 0 reads as 1) of `per_page` blocks (0 = all).
    pub fn new(number: u32, per_page: u32) -> Page {
        let number = number.max(1);
        if per_page == 0 {
            return Page {
                number: 1,
                first: 0,
                end: u32::MAX,
            };
        }
        let first = (number - 1).saturating_mul(per_page);
        Page {
            number,
            first,
            end: first.saturating_add(per_page),
        }
    }

    pub fn contains(&self, seq: u32) -> bool {
        (self.first..self.end).contains(&seq)
    }

    /// Pages of a program of `blocks` blocks (at least 1).
    pub fn count(blocks: u32, per_page: u32) -> u32 {
        if per_page == 0 {
            1
        } else {
            blocks.div_ceil(per_page).max(1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn r387_pages() {
        let mut c = Constants::new();
        assert_eq!(blocks_per_page(&c), 0);
        c.set(387, 50.0);
        assert_eq!(blocks_per_page(&c), 50_000);
        let p = Page::new(2, 10);
        assert_eq!((p.first, p.end), (10, 20));
        assert!(p.contains(10) && p.contains(19) && !p.contains(20) && !p.contains(9));
        assert_eq!(Page::count(21, 10), 3);
        assert_eq!(Page::count(0, 10), 1);
        assert_eq!(Page::new(3, 0), Page::new(1, 0));
        assert!(Page::new(1, 0).contains(4_000_000));
    }
}
