//! Embeds the browser HMI's built files (`hmi/dist/`, issue #30) into cncd: writes
//! `$OUT_DIR/hmi_assets.rs`, a table of `(path, include_bytes!(file))`. Building needs only
//! cargo: without `hmi/dist/` the table is empty and cncd's `/` says the assets are missing.
use std::path::{Path, PathBuf};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?);
    let hmi = manifest.join("../hmi");
    let dist = hmi.join("dist");
    println!("cargo:rerun-if-changed=build.rs");
    // A watched path that does not exist reruns the script on every build: watch the nearest
    // folder that does (a new or removed `dist/` changes `hmi/`).
    if dist.is_dir() {
        println!("cargo:rerun-if-changed={}", dist.display());
    } else if hmi.is_dir() {
        println!("cargo:rerun-if-changed={}", hmi.display());
    }
    let mut files = Vec::new();
    if dist.is_dir() {
        collect(&dist, &dist, &mut files)?;
    }
    files.sort();
    let mut out =
        String::from("/// The files of `hmi/dist/` at build time: path (`/`-separated), bytes.\n");
    out.push_str("pub static EMBEDDED: &[(&str, &[u8])] = &[\n");
    for (rel, abs) in &files {
        out.push_str(&format!("    ({rel:?}, include_bytes!({abs:?})),\n"));
    }
    out.push_str("];\n");
    let dest = PathBuf::from(std::env::var("OUT_DIR")?).join("hmi_assets.rs");
    std::fs::write(dest, out)?;
    Ok(())
}

/// Every regular file under `dir` (hidden files skipped) as (path relative to `root`, absolute).
fn collect(
    root: &Path,
    dir: &Path,
    out: &mut Vec<(String, String)>,
) -> Result<(), Box<dyn std::error::Error>> {
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let p = e.path();
        if e.file_name().to_string_lossy().starts_with('.') {
            continue;
        }
        if p.is_dir() {
            collect(root, &p, out)?;
        } else if p.is_file() {
            let rel = p.strip_prefix(root)?;
            let rel: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            let abs = p.canonicalize()?;
            out.push((rel.join("/"), abs.to_string_lossy().into_owned()));
        }
    }
    Ok(())
}
