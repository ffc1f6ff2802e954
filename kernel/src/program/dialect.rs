//! Which language a program is written in (docs/language.md): the CNC836 dialect of the
//! manuals, or ISO / RS274-NGC as LinuxCNC 2.9 reads it. Both produce the same blocks.

/// A program's language.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Dialect {
    /// The CNC836 / CNC8x9 dialect (SPEC §2): the default.
    #[default]
    Cnc836,
    /// ISO / RS274-NGC as LinuxCNC 2.9 reads it (what CAM systems post).
    Iso,
}

/// File extensions that name an ISO program whatever the machine's default dialect. `.nc` is
/// not one of them: CNC836 programs are commonly kept as `.nc` (this project's examples are),
/// so a `.nc` file follows the machine's default.
pub const ISO_EXTENSIONS: [&str; 3] = ["ngc", "tap", "gcode"];

impl Dialect {
    /// The setting's spelling (`cnc836`, `iso`).
    pub fn as_str(self) -> &'static str {
        match self {
            Dialect::Cnc836 => "cnc836",
            Dialect::Iso => "iso",
        }
    }

    /// From the setting's spelling (case-insensitive).
    pub fn from_name(name: &str) -> Option<Self> {
        match name.trim().to_ascii_lowercase().as_str() {
            "cnc836" => Some(Dialect::Cnc836),
            "iso" | "rs274" | "ngc" => Some(Dialect::Iso),
            _ => None,
        }
    }

    /// The dialect of a program file: ISO for the extensions in [`ISO_EXTENSIONS`], the
    /// machine's `default` otherwise.
    pub fn of_file(name: &str, default: Dialect) -> Dialect {
        let ext = name.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase());
        match ext {
            Some(e) if ISO_EXTENSIONS.contains(&e.as_str()) => Dialect::Iso,
            _ => default,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extension_names_iso() {
        assert_eq!(Dialect::of_file("part.NGC", Dialect::Cnc836), Dialect::Iso);
        assert_eq!(Dialect::of_file("P0001", Dialect::Cnc836), Dialect::Cnc836);
        assert_eq!(
            Dialect::of_file("sample.nc", Dialect::Cnc836),
            Dialect::Cnc836
        );
        assert_eq!(Dialect::of_file("sample.nc", Dialect::Iso), Dialect::Iso);
        assert_eq!(Dialect::of_file("P0001", Dialect::Iso), Dialect::Iso);
        assert_eq!(Dialect::from_name("ISO"), Some(Dialect::Iso));
        assert_eq!(Dialect::from_name("fanuc"), None);
    }
}
