//! Embedded WGSL and the tiny `#import` step that composes it.
//!
//! Every file under `shaders/` is embedded with `include_str!` (so the binary runs from any
//! directory) and listed in [`FILES`]. A line `#import path/to/file.wgsl` is replaced by that
//! file, once per composed module however often it is imported. A few imports are *virtual*:
//! their text is supplied by the caller, e.g. `#import shadow_technique`, which the renderer fills
//! with the active technique's lookup shader. Adding a shader file: put it under `shaders/` and
//! add one line to [`FILES`] (a test fails if a file is missing from the table).

use std::collections::BTreeSet;

/// Every shader file, by path relative to `shaders/`.
pub const FILES: &[(&str, &str)] = &[
    (
        "common/frame.wgsl",
        include_str!("../shaders/common/frame.wgsl"),
    ),
    (
        "common/lighting.wgsl",
        include_str!("../shaders/common/lighting.wgsl"),
    ),
    (
        "common/particle.wgsl",
        include_str!("../shaders/common/particle.wgsl"),
    ),
    (
        "render/opaque.wgsl",
        include_str!("../shaders/render/opaque.wgsl"),
    ),
    (
        "render/particles.wgsl",
        include_str!("../shaders/render/particles.wgsl"),
    ),
    (
        "render/tonemap.wgsl",
        include_str!("../shaders/render/tonemap.wgsl"),
    ),
    (
        "shadow/none.wgsl",
        include_str!("../shaders/shadow/none.wgsl"),
    ),
    (
        "shadow/osm.wgsl",
        include_str!("../shaders/shadow/osm.wgsl"),
    ),
    (
        "shadow/osm_build.wgsl",
        include_str!("../shaders/shadow/osm_build.wgsl"),
    ),
    (
        "shadow/layered.wgsl",
        include_str!("../shaders/shadow/layered.wgsl"),
    ),
    (
        "shadow/layered_build.wgsl",
        include_str!("../shaders/shadow/layered_build.wgsl"),
    ),
    (
        "shadow/dom.wgsl",
        include_str!("../shaders/shadow/dom.wgsl"),
    ),
    (
        "shadow/dom_build.wgsl",
        include_str!("../shaders/shadow/dom_build.wgsl"),
    ),
    (
        "shadow/fom.wgsl",
        include_str!("../shaders/shadow/fom.wgsl"),
    ),
    (
        "shadow/fom_build.wgsl",
        include_str!("../shaders/shadow/fom_build.wgsl"),
    ),
    (
        "shadow/exact.wgsl",
        include_str!("../shaders/shadow/exact.wgsl"),
    ),
    (
        "shadow/exact_build.wgsl",
        include_str!("../shaders/shadow/exact_build.wgsl"),
    ),
    (
        "shadow/probe.wgsl",
        include_str!("../shaders/shadow/probe.wgsl"),
    ),
    (
        "shadow/has.wgsl",
        include_str!("../shaders/shadow/has.wgsl"),
    ),
    (
        "shadow/has_build.wgsl",
        include_str!("../shaders/shadow/has_build.wgsl"),
    ),
    (
        "render/particle_lighting.wgsl",
        include_str!("../shaders/render/particle_lighting.wgsl"),
    ),
    (
        "render/map_view.wgsl",
        include_str!("../shaders/render/map_view.wgsl"),
    ),
];

/// Name of the virtual import that stands for the active shadow technique's lookup shader.
pub const SHADOW_TECHNIQUE: &str = "shadow_technique";

/// The embedded source of `path`.
pub fn source(path: &str) -> Option<&'static str> {
    FILES.iter().find(|(p, _)| *p == path).map(|(_, s)| *s)
}

/// Composes `entry` with its imports resolved. `virtuals` maps virtual import names to source
/// text (which may import further files). Panics on an unknown import: shader sources are part
/// of the binary and a test composes every one of them.
pub fn compose(entry: &str, virtuals: &[(&str, &str)]) -> String {
    let mut seen = BTreeSet::new();
    let mut out = String::new();
    append(entry, virtuals, &mut seen, &mut out);
    out
}

fn append<'a>(
    name: &'a str,
    virtuals: &[(&'a str, &'a str)],
    seen: &mut BTreeSet<&'a str>,
    out: &mut String,
) {
    if !seen.insert(name) {
        return;
    }
    let text = virtuals
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
        .or_else(|| source(name))
        .unwrap_or_else(|| {
            panic!("shader import `{name}` is neither a file in shaders/ nor supplied")
        });
    out.push_str(&format!("// ---- {name} ----\n"));
    for line in text.lines() {
        match line.trim().strip_prefix("#import ") {
            Some(import) => {
                let import = import.trim();
                // Re-borrow the import name from the table so its lifetime is 'a.
                let import: &'a str = virtuals
                    .iter()
                    .map(|(n, _)| *n)
                    .chain(FILES.iter().map(|(p, _)| *p))
                    .find(|n| *n == import)
                    .unwrap_or_else(|| panic!("shader import `{import}` in `{name}` is unknown"));
                append(import, virtuals, seen, out);
            }
            None => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
}

/// Creates a shader module from composed source, labelled for validation messages.
pub fn module(device: &wgpu::Device, label: &str, source: &str) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn imports_are_resolved_once() {
        let text = compose(
            "render/opaque.wgsl",
            &[(SHADOW_TECHNIQUE, source("shadow/none.wgsl").unwrap())],
        );
        assert_eq!(text.matches("struct Frame {").count(), 1);
        assert!(!text.contains("#import"));
        assert!(text.contains("fn shadow_transmittance"));
    }
}
