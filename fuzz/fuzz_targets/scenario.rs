//! Scenario files: any text is a scenario that passes its own checks, or an error; never a
//! panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(scenario) = vibrissa_io::load_str(text, "fuzz.toml", &[]) {
        // What the reader accepts, the simulator accepts.
        scenario
            .check()
            .expect("a scenario the reader accepted fails its own check");
    }
});
