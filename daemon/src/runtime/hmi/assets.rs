//! The static files of the browser HMI (issue #30): embedded into cncd at build time from
//! `hmi/dist/` (see `daemon/build.rs`), or read from a folder (tests, fixtures). Each file
//! carries its content type, cache policy and entity tag, worked out once.

use std::collections::HashMap;
use std::path::Path;

use bytes::Bytes;
use sha2::{Digest, Sha256};

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/hmi_assets.rs"));
}

/// Cache policy of a file whose name carries a hash of its content: it never changes.
pub const CACHE_IMMUTABLE: &str = "public, max-age=31536000, immutable";
/// Cache policy of every other file (index.html above all): ask again each time; the entity
/// tag makes the answer a 304 when nothing changed, so a new cncd's HMI shows at once.
pub const CACHE_REVALIDATE: &str = "no-cache";

/// One file to serve.
#[derive(Clone, Debug)]
pub struct Asset {
    pub bytes: Bytes,
    pub content_type: String,
    pub cache_control: &'static str,
    /// Quoted strong entity tag (a hash of the content).
    pub etag: String,
}

/// The HMI's files by path (`index.html`, `assets/app-3F2A9C1B.js`; no leading `/`).
#[derive(Clone, Debug, Default)]
pub struct Assets {
    files: HashMap<String, Asset>,
}

impl Assets {
    /// The files embedded at build time (none when `hmi/dist/` did not exist).
    pub fn embedded() -> Assets {
        Assets::from_files(
            embedded::EMBEDDED
                .iter()
                .map(|(p, b)| (p.to_string(), Bytes::from_static(b))),
        )
    }

    /// Every file under `dir` (hidden ones skipped), e.g. a test fixture.
    pub fn from_dir(dir: &Path) -> std::io::Result<Assets> {
        let mut files = Vec::new();
        read_dir(dir, "", &mut files)?;
        Ok(Assets::from_files(files))
    }

    /// Files given as (path, content).
    pub fn from_files(files: impl IntoIterator<Item = (String, Bytes)>) -> Assets {
        let files = files
            .into_iter()
            .map(|(path, bytes)| {
                let a = Asset {
                    content_type: content_type(&path),
                    cache_control: cache_policy(&path),
                    etag: etag(&bytes),
                    bytes,
                };
                (path, a)
            })
            .collect();
        Assets { files }
    }

    pub fn get(&self, path: &str) -> Option<&Asset> {
        self.files.get(path)
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    pub fn len(&self) -> usize {
        self.files.len()
    }
}

fn read_dir(dir: &Path, prefix: &str, out: &mut Vec<(String, Bytes)>) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        let rel = format!("{prefix}{name}");
        if e.file_type()?.is_dir() {
            read_dir(&e.path(), &format!("{rel}/"), out)?;
        } else {
            out.push((rel, Bytes::from(std::fs::read(e.path())?)));
        }
    }
    Ok(())
}

/// The content type by extension; text types say UTF-8 (the HMI's files are).
pub fn content_type(path: &str) -> String {
    let t = mime_guess::from_path(path)
        .first_raw()
        .unwrap_or("application/octet-stream");
    let textual = t.starts_with("text/")
        || t == "application/javascript"
        || t == "application/json"
        || t == "image/svg+xml";
    if textual {
        format!("{t}; charset=utf-8")
    } else {
        t.to_string()
    }
}

/// Immutable when the file is under `assets/` (the bundler's output folder) or its name ends
/// in a content hash (`app-5XCCWSTC.js`, `index.BdKq93Lx.css`); else revalidated.
pub fn cache_policy(path: &str) -> &'static str {
    if path.starts_with("assets/") || has_content_hash(path) {
        CACHE_IMMUTABLE
    } else {
        CACHE_REVALIDATE
    }
}

/// Whether the file name's stem ends in `-HASH` or `.HASH`: 8 or more letters and digits, with
/// at least one digit (so `index-overview.js` is not taken for one).
fn has_content_hash(path: &str) -> bool {
    let name = path.rsplit('/').next().unwrap_or(path);
    let stem = name.rsplit_once('.').map_or(name, |(s, _)| s);
    let Some((_, tail)) = stem.rsplit_once(['-', '.']) else {
        return false;
    };
    tail.len() >= 8
        && tail.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && tail.chars().any(|c| c.is_ascii_digit())
}

fn etag(bytes: &[u8]) -> String {
    let d = Sha256::digest(bytes);
    let hex: String = d[..12].iter().map(|b| format!("{b:02x}")).collect();
    format!("\"{hex}\"")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hashed_names_are_immutable_and_pages_revalidate() {
        assert_eq!(cache_policy("index.html"), CACHE_REVALIDATE);
        assert_eq!(cache_policy("app-5XCCWSTC.js"), CACHE_IMMUTABLE);
        assert_eq!(cache_policy("assets/index.BdKq93Lx.css"), CACHE_IMMUTABLE);
        assert_eq!(cache_policy("index-overview.js"), CACHE_REVALIDATE);
        assert_eq!(cache_policy("favicon.svg"), CACHE_REVALIDATE);
    }

    #[test]
    fn content_types_by_extension() {
        assert_eq!(content_type("index.html"), "text/html; charset=utf-8");
        assert!(content_type("a.js").contains("javascript"));
        assert_eq!(content_type("a.css"), "text/css; charset=utf-8");
        assert_eq!(content_type("a.png"), "image/png");
        assert_eq!(content_type("a.woff2"), "font/woff2");
    }
}
