//! The code page of program texts (issue #31): programs from the original controllers carry
//! Czech comments and remarks in legacy code pages (windows-1250, DOS cp852 and Kamenický).
//! Decoding is a pure function of the bytes; every door (upload, validate, load, run, the
//! library) decodes with the configured page before the words are read. The pages are ASCII
//! in their lower half, so the words stay ASCII: a non-ASCII byte outside a comment decodes to
//! a letter the word reader refuses (`unexpected_character`), as before.

use std::borrow::Cow;

use super::code_pages::{CP852, KAMENICKY};

/// `[program] encoding`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TextEncoding {
    /// UTF-8 (the default): a text that is not UTF-8 is refused (`text_not_utf8`).
    #[default]
    Utf8,
    /// Microsoft Central European, Windows 3.1 and later (encoding_rs).
    Windows1250,
    /// IBM DOS Latin 2.
    Cp852,
    /// Kamenický (KEYBCS2), the Czech DOS page of the 1980s and 90s.
    Kamenicky,
}

impl TextEncoding {
    /// Every setting with its name in the configuration.
    pub const ALL: [(TextEncoding, &'static str); 4] = [
        (TextEncoding::Utf8, "utf-8"),
        (TextEncoding::Windows1250, "windows-1250"),
        (TextEncoding::Cp852, "cp852"),
        (TextEncoding::Kamenicky, "kamenicky"),
    ];

    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(e, _)| *e == self)
            .map_or("", |e| e.1)
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(_, n)| *n == name).map(|e| e.0)
    }

    /// The text of `bytes` (a line or a whole program). `None` only for UTF-8 when the bytes
    /// are not UTF-8 (the caller locates the byte); the single-byte pages decode every byte
    /// (a byte windows-1250 leaves undefined becomes U+FFFD).
    pub fn decode(self, bytes: &[u8]) -> Option<Cow<'_, str>> {
        if bytes.is_ascii() {
            // (ASCII is the same in every page: no copy.)
            return std::str::from_utf8(bytes).ok().map(Cow::Borrowed);
        }
        match self {
            TextEncoding::Utf8 => std::str::from_utf8(bytes).ok().map(Cow::Borrowed),
            TextEncoding::Windows1250 => Some(
                encoding_rs::WINDOWS_1250
                    .decode_without_bom_handling(bytes)
                    .0,
            ),
            TextEncoding::Cp852 => Some(Cow::Owned(by_table(bytes, &CP852))),
            TextEncoding::Kamenicky => Some(Cow::Owned(by_table(bytes, &KAMENICKY))),
        }
    }
}

fn by_table(bytes: &[u8], upper: &[char; 128]) -> String {
    bytes
        .iter()
        .map(|&b| {
            if b < 0x80 {
                b as char
            } else {
                upper[usize::from(b - 0x80)]
            }
        })
        .collect()
}

/// Fuzzing entry of the legacy code pages (`fuzz/`, issue #50): arbitrary bytes decoded in
/// every encoding a program may be stored in. Must never panic; a DOS code page or
/// windows-1250 gives one character per byte, UTF-8 only valid text.
pub fn fuzz_entry(data: &[u8]) {
    for (enc, _) in TextEncoding::ALL {
        match (enc, enc.decode(data)) {
            (TextEncoding::Utf8, text) => {
                assert_eq!(text.is_some(), std::str::from_utf8(data).is_ok());
            }
            (_, Some(text)) => assert_eq!(text.chars().count(), data.len()),
            (_, None) => panic!("{} refused bytes", enc.name()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// "Hrubování čepu" (roughing the pin) and "Řez" in each page.
    #[test]
    fn czech_comments_decode_in_every_page() {
        let cases: [(TextEncoding, &[u8]); 3] = [
            (
                TextEncoding::Windows1250,
                b"; Hrubov\xe1n\xed \xe8epu, \xd8ez",
            ),
            (TextEncoding::Cp852, b"; Hrubov\xa0n\xa1 \x9fepu, \xfcez"),
            (
                TextEncoding::Kamenicky,
                b"; Hrubov\xa0n\xa1 \x87epu, \x9eez",
            ),
        ];
        for (enc, bytes) in cases {
            assert_eq!(
                enc.decode(bytes).as_deref(),
                Some("; Hrubování čepu, Řez"),
                "{enc:?}"
            );
        }
        assert_eq!(TextEncoding::Utf8.decode(b"; \xe8"), None);
        assert_eq!(
            TextEncoding::Utf8.decode("; č".as_bytes()).as_deref(),
            Some("; č")
        );
    }

    /// Samples of Unicode's published CP852.TXT (byte → code point), every row of the table.
    #[test]
    fn cp852_matches_the_published_mapping() {
        let published: [(u8, u32); 10] = [
            (0x80, 0x00C7),
            (0x85, 0x016F),
            (0x9F, 0x010D),
            (0xA6, 0x017D),
            (0xB7, 0x011A),
            (0xC6, 0x0102),
            (0xD2, 0x010E),
            (0xE6, 0x0160),
            (0xF5, 0x00A7),
            (0xFF, 0x00A0),
        ];
        for (b, u) in published {
            assert_eq!(CP852[usize::from(b - 0x80)] as u32, u, "0x{b:02X}");
        }
        // Kamenický keeps CP437's box drawing and maths (0xB0..).
        assert_eq!(KAMENICKY[0xB0 - 0x80], '\u{2591}');
        assert_eq!(KAMENICKY[0xE1 - 0x80], '\u{00DF}');
    }

    #[test]
    fn names_round_trip() {
        for (e, n) in TextEncoding::ALL {
            assert_eq!(TextEncoding::from_name(n), Some(e));
            assert_eq!(e.name(), n);
        }
        assert_eq!(TextEncoding::from_name("latin2"), None);
    }
}
