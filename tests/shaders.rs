//! Every WGSL module the tool compiles parses and validates with naga (no GPU needed), and every
//! file under `shaders/` is embedded.

use std::path::Path;

#[test]
fn every_composed_shader_module_validates() {
    let modules = smokeshadow::shadow::all_shader_modules();
    assert!(modules.len() >= 5);
    let mut failures = Vec::new();
    for (label, source) in &modules {
        let module = match naga::front::wgsl::parse_str(source) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{label}: {}", e.emit_to_string(source)));
                continue;
            }
        };
        let mut validator = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        );
        if let Err(e) = validator.validate(&module) {
            failures.push(format!("{label}: {}", e.emit_to_string(source)));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_shader_file_is_embedded_and_composes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut on_disk = Vec::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "wgsl") {
                on_disk.push(
                    path.strip_prefix(&root)
                        .unwrap()
                        .to_string_lossy()
                        .replace('\\', "/"),
                );
            }
        }
    }
    on_disk.sort();
    let mut embedded: Vec<_> = smokeshadow::shaders::FILES
        .iter()
        .map(|(p, _)| p.to_string())
        .collect();
    embedded.sort();
    assert_eq!(on_disk, embedded, "shaders/ and shaders::FILES differ");
    for (path, text) in smokeshadow::shaders::FILES {
        assert_eq!(
            &std::fs::read_to_string(root.join(path)).unwrap(),
            text,
            "{path}"
        );
    }
}
