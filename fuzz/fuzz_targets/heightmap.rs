//! Height-map decoding (PNG, TIFF, EXR sniffed from the bytes) never panics and never allocates
//! beyond the documented size limit.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = meso_maps::HeightMap::from_bytes(
        std::path::Path::new("fuzz.png"),
        data,
        0.01,
        0.1,
        meso_maps::Border::Wrap,
    ) {
        assert!((m.width() * m.height()) as u64 <= meso_maps::heightmap::MAX_TEXELS);
    }
});
