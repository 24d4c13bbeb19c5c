// For layered build shaders whose `prepare_values` returns every packed channel at once (fom,
// msm, tmsm): render target `index` gets channels 4·index ..= 4·index + 3.

fn target_values(prepared: array<f32, 32>, index: u32) -> vec4<f32> {
    var c = prepared;
    let i = index * 4u;
    return vec4<f32>(c[i], c[i + 1u], c[i + 2u], c[i + 3u]);
}
