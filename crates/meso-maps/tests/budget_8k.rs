//! An 8192² height map is accepted by `meso extract` under the default memory budget (4 GiB):
//! the streamed extraction's estimate (`check_budget_streamed`: the larger of the image's load
//! and the heights + `extract_stream_bytes`, with the horizon angles in 16 bits) is checked on
//! the header of a 16-bit grey PNG of that size, built by hand (only its header is read). One
//! test per binary: the budget is process-wide.

use meso_maps::input::check_budget_streamed;
use meso_maps::{Border, ExtractParams, InputKind};

/// CRC-32 (ISO-HDLC, as PNG uses) of `bytes`.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let crc = crc32(&out[start..]);
    out.extend_from_slice(&crc.to_be_bytes());
}

/// A PNG whose header says `side × side`, 16-bit grey; its image data is a stub (never decoded
/// here).
fn png_header(side: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&side.to_be_bytes());
    ihdr.extend_from_slice(&side.to_be_bytes());
    ihdr.extend_from_slice(&[16, 0, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &ihdr);
    chunk(
        &mut out,
        b"IDAT",
        &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
    );
    chunk(&mut out, b"IEND", &[]);
    out
}

#[test]
fn an_8k_height_map_fits_the_default_budget() {
    let dir = std::env::temp_dir().join(format!("meso-maps-8k-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let kind = InputKind::Heights {
        texel_size: 1.0,
        height_scale: 1.0,
        border: Border::Wrap,
    };
    let params = ExtractParams::default();
    let path = dir.join("h8k.png");
    std::fs::write(&path, png_header(8192)).unwrap();
    meso_core::budget::set_budget(meso_core::budget::DEFAULT_BUDGET_BYTES);
    check_budget_streamed(&path, kind, &params).expect("8192² within the default 4 GiB");
    // The estimate is ≈ 3.97 GB (docs/limits.md): 3.5 GiB refuses it, naming the file.
    meso_core::budget::set_budget(3584 << 20);
    let e = check_budget_streamed(&path, kind, &params)
        .unwrap_err()
        .to_string();
    assert!(e.contains("h8k.png") && e.contains("memory"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
