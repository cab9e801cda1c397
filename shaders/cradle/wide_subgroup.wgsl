// wide.wgsl's reduction with subgroup operations (wgpu's SUBGROUP feature):
// within a subgroup by shuffles, in registers, then the subgroups' results
// through workgroup memory. A workgroup of MAX_BALLS invocations is
// MAX_BALLS / lanes subgroups of `lanes` (powers of two both; a subgroup
// wider than the workgroup holds it whole, its other lanes inactive).
// It stands for what engine::cradle::lanes accumulates in its loops over
// the chain (the earliest onset, the step's caps, overlaps, onsets).

// The invocation's place in the dispatch and in its subgroup.
struct Lane {
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(subgroup_invocation_id) sid: u32,
    @builtin(subgroup_size) size: u32,
    @builtin(subgroup_id) group: u32,
}

// This invocation's lane in its subgroup, its subgroup, the workgroup's
// active lanes per subgroup and its subgroups.
var<private> sid: u32;
var<private> group: u32;
var<private> lanes: u32;
var<private> parts: u32;

// This invocation's index (`me`) and lane; returns its workgroup's (the worker's).
fn enter(lane: Lane) -> u32 {
    me = lane.lid;
    sid = lane.sid;
    group = lane.group;
    lanes = min(lane.size, MAX_BALLS);
    parts = MAX_BALLS / lanes;
    return lane.wid.x;
}

// `x` of every invocation combined (`op`); every invocation gets the result.
// Each subgroup folds its lanes by shuffles (lane l takes lane l + s's value,
// s = lanes/2 … 1: lane 0 ends with the subgroup's); with one subgroup
// lane 0's result is broadcast, else each subgroup's lane 0 writes it to
// workgroup memory and every invocation combines them in order. One barrier
// for a workgroup of one subgroup (the tree: 2 + log2(MAX_BALLS)), two for
// several. The first orders whatever the caller wrote or read before the
// call against what it writes or reads after (callers rely on that; the
// shuffles order nothing in memory).
fn reduce(x: Red, op: u32) -> Red {
    workgroupBarrier(); // the caller's writes are seen; the last result has been read
    var r = x;
    for (var s = lanes / 2u; s > 0u; s = s / 2u) {
        // every lane shuffles (a lane past `lanes` is inactive: nobody reads it)
        let y = Red(subgroupShuffleDown(r.a, s), subgroupShuffleDown(r.b, s), subgroupShuffleDown(r.c, s), subgroupShuffleDown(r.u, s));
        if (sid < s) {
            r = combine(r, y, op);
        }
    }
    if (parts == 1u) {
        return Red(subgroupBroadcast(r.a, 0u), subgroupBroadcast(r.b, 0u), subgroupBroadcast(r.c, 0u), subgroupBroadcast(r.u, 0u));
    }
    if (sid == 0u) {
        red[group] = r;
    }
    workgroupBarrier();
    var t = red[0];
    for (var g = 1u; g < parts; g++) {
        t = combine(t, red[g], op);
    }
    return t;
}
