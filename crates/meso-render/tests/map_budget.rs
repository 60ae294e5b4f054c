//! The memory check of a map file's material (`[texture] map = "…"`, what `meso render`
//! builds): the pyramid held and the least cache of tables (`MIN_TABLE_CACHE`, or every tile's
//! tables when fewer) against the budget, refused one byte under it with a message naming the
//! file, built at it. Its own test binary: it sets the process's budget.

use meso_core::material::Material;
use meso_maps::{extract, fixtures, ExtractParams, MapsResolver, Pyramid, Source};
use meso_render::textured::MIN_TABLE_CACHE;
use meso_render::{load_textured, NdfMapped};
use std::path::Path;

#[test]
fn the_material_of_a_map_file_is_budgeted() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("map_budget");
    std::fs::create_dir_all(&dir).unwrap();
    let map = fixtures::gaussian(64, 4.0, 0.1, 3, 0.01).unwrap();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let path = dir.join("g64.map");
    pyr.write(&path).unwrap();
    let transfer = "[transfer]\nkind = \"phong\"\nexponent = 20.0\n";
    let mat = dir.join("mat.toml");
    std::fs::write(
        &mat,
        format!("[texture]\nkind = \"ndf-mapped\"\nmap = \"g64.map\"\n{transfer}"),
    )
    .unwrap();
    let read = Pyramid::read_lazy(&path).unwrap();
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
}
