//! Creased surfaces whose walls are one or two cells wide, at two map sizes: the default
//! height-map far field (`meso brdf` of a `kind = "heightmap"` material: facets with their
//! normal-conditioned visibility) against the ray-traced gonioreflectometer (256² rays per pair),
//! relative RMSE over the 16 direction pairs of `fixtures::farfield_pairs` (θ ≤ 60°),
//! `√(Σ(f − g)²/Σ g²)`. The same surface tiled to 128² must give the same figure as at 64²: the
//! truth does not change with the tiling (docs/heightmaps.md, "Points per facet").
//!
//! ```text
//! cargo run --release -p meso-maps --example narrow_grooves
//! ```
use meso_core::material::Material;
use meso_maps::*;

const TRANSFERS: [(&str, &str); 3] = [
    ("Lambert", "[transfer]\nkind = \"lambert\"\nalbedo = [1.0, 1.0, 1.0]\n"),
    (
        "Beckmann 0.2",
        "[transfer]\nkind = \"microfacet\"\ndistribution = \"beckmann\"\nalpha = 0.2\nfresnel = \"none\"\n",
    ),
    (
        "Beckmann 0.1",
        "[transfer]\nkind = \"microfacet\"\ndistribution = \"beckmann\"\nalpha = 0.1\nfresnel = \"none\"\n",
    ),
];

fn main() {
    let dir = std::env::temp_dir().join(format!("meso-grooves-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::env::set_var("MESO_CACHE_DIR", "off");
    let s = 1.0 / 64.0;
    let pairs = fixtures::farfield_pairs();
    let gp = GonioParams {
        rays_per_side: 256,
        ..GonioParams::default()
    };
    println!("| surface | facets | 64² | 128² (the same surface tiled) |");
    println!("|---|---|---|---|");
    type Make = fn(usize, f64) -> HeightMap;
    let surfaces: [(&str, Make); 5] = [
        ("V-grooves 45°, period 2", |n, s| {
            fixtures::v_grooves(n, 2, s, s).unwrap()
        }),
        ("V-grooves 56°, period 4", |n, s| {
            fixtures::v_grooves(n, 4, 3.0 * s, s).unwrap()
        }),
        ("V-grooves 45°, period 4", |n, s| {
            fixtures::v_grooves(n, 4, 2.0 * s, s).unwrap()
        }),
        ("half-cylinders, period 4", |n, s| {
            fixtures::half_cylinders(n, 4, s, 1.0).unwrap()
        }),
        ("half-cylinder grooves, period 4", |n, s| {
            fixtures::half_cylinders(n, 4, s, -1.0).unwrap()
        }),
    ];
    for (name, make) in surfaces {
        for (tname, t) in TRANSFERS {
            let mut row = format!("| {name} | {tname} |");
            for n in [64, 128] {
                let map = make(n, s);
                let (png, scale) = map.encode_png16().unwrap();
                let file = dir.join(format!("h{n}.png"));
                std::fs::write(&file, png).unwrap();
                let text = format!(
                    "[ndf]\nkind = \"heightmap\"\nfile = \"h{n}.png\"\ntexel_size = {s}\nheight_scale = {scale}\n{t}"
                );
                let mf = dir.join("m.toml");
                std::fs::write(&mf, text).unwrap();
                let m = Material::from_file(&mf, &MapsResolver::new()).unwrap();
                let loaded = HeightMap::load(&file, s, scale, Border::Wrap).unwrap();
                let g = Gonio::new(&loaded).unwrap();
                let (mut num, mut den) = (0.0, 0.0);
                for &(i, o) in &pairs {
                    let truth = g.measure(&m.transfer, i, o, &gp)[0];
                    num += (m.brdf(i, o)[0] - truth).powi(2);
                    den += truth * truth;
                }
                row += &format!(" {:.1}% |", 100.0 * (num / den).sqrt());
            }
            println!("{row}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
