//! Embeds every shader under the workspace's `shaders/`: writes `$OUT_DIR/shader_files.rs`, the
//! table `core/src/shaders.rs` includes, so a new `.wgsl` file needs no edit anywhere to be
//! compiled in.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn main() {
    // Read when the script runs, not baked in when it is compiled: a target folder shared by two
    // checkouts reuses one compiled script, which must read the shaders of the checkout it runs
    // for.
    let root = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"))
        .join("../shaders");
    println!("cargo:rerun-if-changed=../shaders");
    let mut files = Vec::new();
    collect(&root, &mut files);
    // Sorted, so the table (and anything iterating it) never depends on directory order.
    files.sort();
    let mut out = String::from("&[\n");
    for path in &files {
        let relative = path
            .strip_prefix(&root)
            .expect("collected under shaders/")
            .to_str()
            .expect("shader paths are UTF-8")
            .replace('\\', "/");
        println!("cargo:rerun-if-changed={}", path.display());
        writeln!(
            out,
            "    ({relative:?}, include_str!({:?})),",
            path.display().to_string()
        )
        .expect("writing to a String");
    }
    out.push(']');
    let dest = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"))
        .join("shader_files.rs");
    std::fs::write(&dest, out).expect("OUT_DIR is writable");
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    for entry in entries {
        let path = entry.expect("readable shaders/ entry").path();
        if path.is_dir() {
            collect(&path, out);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            out.push(path);
        }
    }
}
