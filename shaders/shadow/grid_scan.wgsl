// The exclusive prefix sum of a square grid's counts into list offsets, in three steps, each
// dispatched in a pass of its own (src/shadow/exact.rs, src/shadow/deep_capture.rs):
// scan_rows sums each row's counts, scan_total scans the row sums (one invocation: a side has at
// most a few thousand rows), scan_write writes each row's offsets; offsets[side²] = the total.
// The importer declares `counts: array<atomic<u32>>` (side² counts, and anything it keeps after
// them), `offsets: array<u32>` (side² + 1), `row_sums: array<u32>` (side + 1) and
// `fn scan_side() -> u32`.

@compute @workgroup_size(64)
fn scan_rows(@builtin(global_invocation_id) id: vec3<u32>) {
    let side = scan_side();
    let row = id.x;
    if row >= side {
        return;
    }
    var sum = 0u;
    for (var x = 0u; x < side; x++) {
        sum += atomicLoad(&counts[row * side + x]);
    }
    row_sums[row] = sum;
}

@compute @workgroup_size(1)
fn scan_total() {
    let side = scan_side();
    var running = 0u;
    for (var row = 0u; row < side; row++) {
        let sum = row_sums[row];
        row_sums[row] = running;
        running += sum;
    }
    row_sums[side] = running;
    offsets[side * side] = running;
}

@compute @workgroup_size(64)
fn scan_write(@builtin(global_invocation_id) id: vec3<u32>) {
    let side = scan_side();
    let row = id.x;
    if row >= side {
        return;
    }
    var running = row_sums[row];
    for (var x = 0u; x < side; x++) {
        let index = row * side + x;
        offsets[index] = running;
        running += atomicLoad(&counts[index]);
    }
}
