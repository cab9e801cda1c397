//! Fuzz the scene and sweep parsers and validation: any input must give a
//! value or a typed error, never a panic.
#![no_main]

use hertz_cradle::error::Source;
use hertz_cradle::scene::SceneSpec;
use hertz_cradle::sweep::Sweep;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let src = Source::new("fuzz.toml", text);
    if let Ok(spec) = SceneSpec::parse(&src) {
        if let Ok(scene) = spec.validate() {
            let _ = hertz_cradle::engine::Chain::from_scene(&scene);
        }
    }
    if let Ok(sweep) = Sweep::parse(&src, std::path::Path::new("/nonexistent")) {
        // expand a few scenes: first, last and middle ids
        for id in [0, sweep.total / 2, sweep.total - 1] {
            let _ = sweep.scene(id);
            let _ = sweep.axis_fields(id);
        }
    }
});
