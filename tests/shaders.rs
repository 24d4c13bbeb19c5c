//! Every WGSL module the tool compiles parses and validates with naga (no GPU needed), and every
//! file under `shaders/` is embedded.

use std::path::Path;

#[test]
fn every_composed_shader_module_validates() {
    let mut modules = smokeshadow::shadow::all_shader_modules();
    modules.extend(smokeshadow::medium::gpu_grid::shader_modules());
    modules.extend(smokeshadow::medium::cloud::shader_modules());
    modules.extend(smokeshadow::medium::eye::shader_modules());
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

/// Every `#[repr(C)]` Rust struct that a shader reads as a uniform or storage struct, held against
/// naga's reflection of the WGSL struct: the same size, and every named field at the same offset.
#[test]
fn every_rust_mirror_matches_nagas_reflection_of_its_wgsl_struct() {
    use smokeshadow::shaders::compose;
    use smokeshadow::shadow::{
        deep_capture, deep_nodes, exact, half_angle, layered, light_maps, volume,
    };
    let mirrors = [
        smokeshadow::frame::gpu_data::layouts(),
        smokeshadow::frame::particles::layouts(),
        smokeshadow::render::history::layouts(),
        layered::layouts(),
        exact::layouts(),
        deep_capture::layouts(),
        deep_nodes::layouts(),
        half_angle::layouts(),
        light_maps::layouts(),
        volume::layouts(),
        smokeshadow::viewer::map_view::layouts(),
        smokeshadow::render::mixed_res::layouts(),
        smokeshadow::medium::gpu_grid::layouts(),
        smokeshadow::medium::cloud_noise::layouts(),
        smokeshadow::medium::eye::layouts(),
        smokeshadow::medium::cloud::layouts(),
        smokeshadow::medium::eye_pass::layouts(),
        smokeshadow::shadow::srm::layouts(),
    ]
    .concat();
    // `none`'s lookup and the occluders' map for the frame shaders' virtual imports.
    let params = smokeshadow::shadow::TechniqueParams {
        occluders: smokeshadow::shadow::OccluderMode::Map,
        ..smokeshadow::shadow::TechniqueParams::new(24, 512)
    };
    let imports = smokeshadow::shadow::frame_baseline().frame_imports(&params);
    for m in &mirrors {
        let text = compose(m.wgsl_file, &imports.pairs());
        let module = naga::front::wgsl::parse_str(&text)
            .unwrap_or_else(|e| panic!("{}: {}", m.wgsl_file, e.emit_to_string(&text)));
        let (members, span) = module
            .types
            .iter()
            .find_map(|(_, ty)| match (&ty.name, &ty.inner) {
                (Some(name), naga::TypeInner::Struct { members, span })
                    if name == m.wgsl_struct =>
                {
                    Some((members.clone(), *span))
                }
                _ => None,
            })
            .unwrap_or_else(|| panic!("{} declares no struct {}", m.wgsl_file, m.wgsl_struct));
        assert_eq!(
            m.size, span as usize,
            "{} is {} bytes, WGSL {} is {span}",
            m.rust, m.size, m.wgsl_struct
        );
        let named: Vec<_> = members
            .iter()
            .filter(|mem| mem.name.as_deref().is_some_and(|n| !n.starts_with('_')))
            .map(|mem| (mem.name.clone().unwrap(), mem.offset as usize))
            .collect();
        let rust: Vec<_> = m
            .fields
            .iter()
            .filter(|(n, _)| !n.starts_with('_'))
            .map(|(n, o)| ((*n).to_owned(), *o))
            .collect();
        assert_eq!(rust, named, "{} against WGSL {}", m.rust, m.wgsl_struct);
    }
}
