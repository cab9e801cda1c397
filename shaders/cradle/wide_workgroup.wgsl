// wide.wgsl's reduction over workgroup memory, for adapters without
// subgroup operations (or with them turned off: the profile's `subgroups`).
// It stands for what engine::cradle::lanes accumulates in its loops over
// the chain (the earliest onset, the step's caps, overlaps, onsets).

// The invocation's place in the dispatch.
struct Lane {
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
}

// This invocation's index (`me`); returns its workgroup's (the worker's).
fn enter(lane: Lane) -> u32 {
    me = lane.lid;
    return lane.wid.x;
}

// `x` of every invocation combined (`op`); every invocation gets the result.
// A tree over workgroup memory: log2(MAX_BALLS) levels, a barrier each. Its
// first barrier orders whatever the caller wrote or read before it against
// what it writes or reads after (callers rely on that).
fn reduce(x: Red, op: u32) -> Red {
    workgroupBarrier(); // the last reduction's result has been read
    red[me] = x;
    workgroupBarrier();
    for (var s = MAX_BALLS / 2u; s > 0u; s = s / 2u) {
        if (me < s) {
            red[me] = combine(red[me], red[me + s], op);
        }
        workgroupBarrier();
    }
    return red[0];
}
