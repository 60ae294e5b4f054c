//! The memory check of a map file's material (`[texture] map = "…"`, what `meso render`
//! builds): the pyramid held and the least cache of tables (`MIN_TABLE_CACHE`, or every tile's
//! tables when fewer) against the budget, refused one byte under it with a message naming the
//! file, built at it; and what `meso render` reads a map file as (`Pyramid::read_compact`):
//! coded when that takes at most half the budget, level 0 held by band when more. Its own test
//! binary: it sets the process's budget.

use meso_core::material::Material;
use meso_maps::{extract, fixtures, ExtractParams, Lobes, MapsResolver, Pyramid, Source};
use meso_render::textured::MIN_TABLE_CACHE;
use meso_render::{load_textured, NdfMapped};
use std::path::{Path, PathBuf};

/// The map file of an `n`² Gaussian surface, extracted with the defaults, as `dir/gN.map`.
fn written(dir: &Path, n: usize) -> PathBuf {
    let map = fixtures::gaussian(n, 4.0, 0.1, 3, 0.01).unwrap();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let path = dir.join(format!("g{n}.map"));
    pyr.write(&path).unwrap();
    path
}

#[test]
fn the_material_of_a_map_file_is_budgeted() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("map_budget");
    std::fs::create_dir_all(&dir).unwrap();
    let path = written(&dir, 64);
    let transfer = "[transfer]\nkind = \"phong\"\nexponent = 20.0\n";
    let mat = dir.join("mat.toml");
    std::fs::write(
        &mat,
        format!("[texture]\nkind = \"ndf-mapped\"\nmap = \"g64.map\"\n{transfer}"),
    )
    .unwrap();
    let read = Pyramid::read_compact(&path).unwrap();
    let surface = Material::from_toml_str(transfer).unwrap();
    let bound = NdfMapped::tables_bytes_bound(&read, &surface, true);
    let need = NdfMapped::pyramid_bytes(&read) + bound.min(MIN_TABLE_CACHE);
    eprintln!(
        "pyramid {} B, tables at most {bound} B: need {need} B",
        NdfMapped::pyramid_bytes(&read)
    );
    meso_core::budget::set_budget(need - 1);
    let e = match load_textured(&mat, &MapsResolver::new()) {
        Err(e) => e,
        Ok(_) => panic!("built over the budget"),
    };
    assert!(
        e.contains("g64.map")
            && e.contains("rendering the map file (its pyramid and the least cache of tables)")
            && e.contains("memory budget"),
        "{e}"
    );
    meso_core::budget::set_budget(need);
    assert!(matches!(
        load_textured(&mat, &MapsResolver::new()),
        Ok(Some(_))
    ));
    meso_core::budget::set_budget(0);

    // A map whose level 0 is compact (256² ≥ COMPACT_TEXELS) is read coded under the default
    // budget, and still coded under a budget it takes more than half of: level 0 held by
    // band would need more here (its cache of decoded bands is all of a small level 0 and
    // more). The choice itself: `lazy_pays` in meso-maps' format/v4.rs; a level held by
    // band: meso-maps' tests/map_lazy.rs.
    let path = written(&dir, 256);
    let coded = Pyramid::read_compact(&path).unwrap();
    assert!(matches!(coded.levels[0].lobes, Lobes::Coded(_)));
    let held = NdfMapped::pyramid_bytes(&coded);
    meso_core::budget::set_budget(held * 2);
    let again = Pyramid::read_compact(&path).unwrap();
    assert!(matches!(again.levels[0].lobes, Lobes::Coded(_)));
    assert!(
        Pyramid::read_lazy(&path).is_err(),
        "held by band, it needs more"
    );
    meso_core::budget::set_budget(0);
}
