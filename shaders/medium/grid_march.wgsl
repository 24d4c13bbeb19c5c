// The light's transmittance through a density grid at a list of world points
// (src/medium/gpu_grid.rs, GridMarch): each point's segment to the light marched with a fixed
// number of steps. The volumes' reference evaluates it at N and 2N steps to show convergence.
#import medium/grid.wgsl

// Keep in sync with `MarchParams` in src/medium/gpu_grid.rs.
struct MarchParams {
    // xyz: the light's position, world metres.
    light: vec4<f32>,
    steps: u32,
    count: u32,
    _pad0: u32,
    _pad1: u32,
};

@group(0) @binding(0) var<uniform> grid: GridParams;
@group(0) @binding(1) var grid_density: texture_3d<f32>;

fn grid_params() -> GridParams {
    return grid;
}
@group(0) @binding(2) var<uniform> march: MarchParams;
// xyz: world point (m), w unused.
@group(0) @binding(3) var<storage, read> march_points: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> march_transmittance: array<f32>;

@compute @workgroup_size(64)
fn march_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= march.count {
        return;
    }
    let p = march_points[id.x].xyz;
    march_transmittance[id.x] = exp(-grid_optical_depth(march.light.xyz, p, march.steps));
}
