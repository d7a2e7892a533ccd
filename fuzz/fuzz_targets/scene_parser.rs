//! Any bytes as a scene file (granular or structural): an error or a scene, never a panic or a hang.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = moreau::scene::parse_any(text, std::path::Path::new("fuzz.toml"));
    }
});
