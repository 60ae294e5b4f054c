//! Which far-field representation should a height-map material use by default? `meso brdf`'s
//! own path (a material file over a height map, through `MapsResolver`) against the ray-traced
//! gonioreflectometer (single bounce, 256² rays per pair) on the surfaces of issue #11: V-grooves,
//! touching half-cylinders and their negative, a plain weave, a Gaussian random surface and a
//! real texture (ambientCG Facade005, 8-bit, tests/data). Relative RMSE over 16 direction pairs
//! with θ ≤ 60°, `√(Σ(f − g)²/Σ g²)`, for Lambert facets and rough conductors (Beckmann α = 0.1
//! and 0.05, no Fresnel). Also the time of 10⁴ pairs for a 256² map with each representation.
//!
//! ```text
//! cargo run --release -p meso-maps --example farfield_table
//! FARFIELD_TIMING=1 cargo run --release -p meso-maps --example farfield_table   # timing only
//! FARFIELD_TIMING=1 FARFIELD_ONLY=visibility cargo run …   # one representation's timing
//! ```
use glam::DVec3;
use meso_core::frame::spherical_direction_deg as d;
use meso_core::material::Material;
use meso_maps::*;
use std::path::Path;
use std::time::Instant;

const TRANSFERS: [(&str, &str); 3] = [
    ("Lambert", "[transfer]\nkind = \"lambert\"\nalbedo = [1.0, 1.0, 1.0]\n"),
    (
        "Beckmann 0.1",
        "[transfer]\nkind = \"microfacet\"\ndistribution = \"beckmann\"\nalpha = 0.1\nfresnel = \"none\"\n",
    ),
    (
        "Beckmann 0.05",
        "[transfer]\nkind = \"microfacet\"\ndistribution = \"beckmann\"\nalpha = 0.05\nfresnel = \"none\"\n",
    ),
];

/// (label, `[ndf]` extra keys, `[shadowing]` kind or none for the default)
const REPRESENTATIONS: [(&str, &str, Option<&str>); 5] = [
    (
        "lobes K=4, Smith (old default)",
        "represent = \"lobes\"\n",
        Some("smith"),
    ),
    (
        "lobes K=4, horizon",
        "represent = \"lobes\"\n",
        Some("horizon"),
    ),
    ("facets, Smith", "represent = \"facets\"\n", Some("smith")),
    (
        "facets, horizon",
        "represent = \"facets\"\n",
        Some("horizon"),
    ),
    (
        "facets, visibility",
        "represent = \"facets\"\n",
        Some("visibility"),
    ),
];

fn pairs() -> Vec<(DVec3, DVec3)> {
    fixtures::farfield_pairs()
}

fn material(
    dir: &Path,
    file: &str,
    s: f64,
    h: f64,
    ndf: &str,
    t: &str,
    sh: Option<&str>,
) -> Material {
    let sh = sh.map_or(String::new(), |k| format!("[shadowing]\nkind = \"{k}\"\n"));
    let text = format!(
        "[ndf]\nkind = \"heightmap\"\nfile = \"{file}\"\ntexel_size = {s}\nheight_scale = {h}\n{ndf}{t}{sh}"
    );
    let p = dir.join("m.toml");
    std::fs::write(&p, text).unwrap();
    Material::from_file(&p, &MapsResolver::new()).unwrap()
}

fn main() {
    let dir = std::env::temp_dir().join(format!("meso-farfield-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    std::fs::copy(data.join("facade_disp_256.png"), dir.join("facade.png")).unwrap();
    let n = 64;
    let s = 1.0 / n as f64;
    let mut surfaces: Vec<(&str, String, f64, f64)> = Vec::new();
    for (name, map) in [
        (
            "V-grooves (63°)",
            fixtures::v_grooves(n, 16, 0.25, s).unwrap(),
        ),
        (
            "half-cylinders",
            fixtures::half_cylinders(n, 16, s, 1.0).unwrap(),
        ),
        (
            "half-cylinder grooves",
            fixtures::half_cylinders(n, 16, s, -1.0).unwrap(),
        ),
        ("plain weave", fixtures::woven(n, 16, 0.06, s).unwrap()),
        ("Gaussian", fixtures::gaussian(n, 3.0, 0.012, 7, s).unwrap()),
    ] {
        let (png, scale) = map.encode_png16().unwrap();
        let file = format!("{}.png", surfaces.len());
        std::fs::write(dir.join(&file), png).unwrap();
        surfaces.push((name, file, s, scale));
    }
    // The real texture: 256² texels over a unit tile, grout 2% of the tile high.
    surfaces.push((
        "facade (8-bit, real)",
        "facade.png".into(),
        1.0 / 256.0,
        0.02,
    ));
    let pairs = pairs();
    // FARFIELD_TIMING=1: the timing table only.
    let timing_only = std::env::var_os("FARFIELD_TIMING").is_some();
    let gp = GonioParams {
        rays_per_side: 256,
        ..GonioParams::default()
    };
    println!(
        "| surface | facets | {} |",
        REPRESENTATIONS.map(|r| r.0).join(" | ")
    );
    println!("|---|---|{}", "---|".repeat(REPRESENTATIONS.len()));
    for (name, file, s, h) in surfaces.iter().filter(|_| !timing_only) {
        let map = HeightMap::load(&dir.join(file), *s, *h, Border::Wrap).unwrap();
        let g = Gonio::new(&map).unwrap();
        for (tname, t) in TRANSFERS {
            let m0 = material(&dir, file, *s, *h, "represent = \"facets\"\n", t, None);
            let truth: Vec<f64> = pairs
                .iter()
                .map(|&(i, o)| g.measure(&m0.transfer, i, o, &gp)[0])
                .collect();
            let den: f64 = truth.iter().map(|v| v * v).sum();
            let mut row = format!("| {name} | {tname} |");
            for (_, ndf, sh) in REPRESENTATIONS {
                let m = material(&dir, file, *s, *h, ndf, t, sh);
                let num: f64 = pairs
                    .iter()
                    .zip(&truth)
                    .map(|(&(i, o), g)| (m.brdf(i, o)[0] - g).powi(2))
                    .sum();
                row += &format!(" {:.1}% |", 100.0 * (num / den).sqrt());
            }
            println!("{row}");
        }
    }
    // Speed: 10⁴ pairs of a 256² map (the Gaussian surface at 256², Beckmann 0.1).
    let map = fixtures::gaussian(256, 3.0, 0.012 / 4.0, 7, 1.0 / 256.0).unwrap();
    let (png, scale) = map.encode_png16().unwrap();
    std::fs::write(dir.join("g256.png"), png).unwrap();
    let many: Vec<(DVec3, DVec3)> = (0..10_000)
        .map(|k| {
            let a = k as f64 * 0.618_033_988_75;
            let b = k as f64 * 0.754_877_666_25;
            (
                d(60.0 * a.fract(), 360.0 * b.fract()),
                d(60.0 * (a * 1.7).fract(), 360.0 * (b * 1.3).fract()),
            )
        })
        .collect();
    println!();
    println!(
        "| 10⁴ pairs, 256² Gaussian map, Beckmann 0.1 | load + build | 10⁴ pairs (wall) | 10⁴ pairs (CPU) |"
    );
    println!("|---|---|---|---|");
    for (label, ndf, sh) in REPRESENTATIONS
        .iter()
        .filter(|r| !timing_only || r.1.contains("facets"))
        // FARFIELD_ONLY=visibility: the representations whose label contains it.
        .filter(|r| std::env::var("FARFIELD_ONLY").map_or(true, |k| r.0.contains(k.as_str())))
    {
        let (ndf, sh) = (*ndf, *sh);
        let t0 = Instant::now();
        let m = material(
            &dir,
            "g256.png",
            1.0 / 256.0,
            scale,
            ndf,
            TRANSFERS[1].1,
            sh,
        );
        let build = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let c1 = cpu_seconds();
        use rayon::prelude::*;
        let sum: f64 = many.par_iter().map(|&(i, o)| m.brdf(i, o)[0]).sum();
        let eval = t1.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - c1;
        println!("| {label} | {build:.2} s | {eval:.2} s | {cpu:.2} s |");
        std::hint::black_box(sum);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// CPU time (user + system) this process has used, in seconds, from `/proc/self/stat` (Linux;
/// NaN elsewhere): unlike wall time it does not grow when other jobs share the cores.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which ends with ')'): utime and stime are the 12th and
    // 13th, in clock ticks of 1/100 s.
    let rest = stat.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |k: usize| {
        f.get(k)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    (ticks(11) + ticks(12)) / 100.0
}
