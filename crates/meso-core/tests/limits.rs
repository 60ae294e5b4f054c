//! Finite but absurd numbers in material files: refused with a message naming the key and
//! the value in exponent notation, or read exactly, never NaN (the CLI audit's item 4).

use meso_core::material::Material;
use meso_core::ndf::Ndf;

const PHONG: &str = "[transfer]\nkind = \"phong\"\nexponent = 20.0\n";

fn phong_axis(axis: &str) -> Result<Material, String> {
    Material::from_toml_str(&format!(
        "[ndf]\nkind = \"phong-peaks\"\nlobes = [{{ axis = {axis}, weight = 1.0, exponent = 10.0 }}]\n{PHONG}"
    ))
    .map_err(|e| e.to_string())
}

/// A vector axis whose length overflows is normalised by its largest component first: the
/// direction it stands for, not NaN.
#[test]
fn a_vector_axis_of_huge_components_is_its_direction() {
    for (axis, want) in [
        ("[1e300, 1e300, 1e300]", glam::DVec3::ONE.normalize()),
        (
            "[0.0, -1e308, 1e308]",
            glam::DVec3::new(0.0, -1.0, 1.0).normalize(),
        ),
        ("[1.7e308, 0.0, 0.0]", glam::DVec3::X),
    ] {
        let m = phong_axis(axis).unwrap();
        let Ndf::PhongPeaks(p) = &m.ndf else {
            panic!("kind")
        };
        let a = p.lobes()[0].axis;
        assert!(a.is_finite(), "{axis}: {a}");
        assert!((a - want).length() < 1e-12, "{axis}: {a} (want {want})");
    }
    // Tiny vectors are still no direction, and the message writes them in exponent notation.
    let e = phong_axis("[1e-300, 0.0, 0.0]").unwrap_err();
    assert!(e.contains("[1e-300, 0, 0] is not a direction"), "{e}");
}

/// A polar angle out of range is written in exponent notation (not 300 digits).
#[test]
fn an_absurd_polar_angle_is_written_short() {
    let e = phong_axis("[1e300, 0.0]").unwrap_err();
    assert!(e.contains("got 1e300"), "{e}");
    assert!(e.len() < 200, "{e}");
}

/// Conductor `eta` and `k` are bounded like the dielectric's `eta` (they gave NaN BRDFs).
#[test]
fn conductor_eta_and_k_are_bounded() {
    let conductor = |eta: &str, k: &str| {
        Material::from_toml_str(&format!(
            "[ndf]\nkind = \"beckmann\"\nalpha = 0.3\n[transfer]\nkind = \"mirror\"\n\
             fresnel = \"conductor\"\neta = {eta}\nk = {k}\n"
        ))
        .map_err(|e| e.to_string())
    };
    conductor("[0.2, 0.9, 1.1]", "[3.9, 2.4, 2.2]").unwrap();
    conductor("[100.0, 0.0, 1.0]", "[0.0, 100.0, 1.0]").unwrap();
    for (eta, k, shown) in [
        (
            "[1e300, 1.0, 1.0]",
            "[1.0, 1.0, 1.0]",
            "eta = [1e300, 1, 1]",
        ),
        ("[1.0, 1.0, 1.0]", "[1.0, 1e300, 1.0]", "k = [1, 1e300, 1]"),
        (
            "[100.5, 1.0, 1.0]",
            "[1.0, 1.0, 1.0]",
            "eta = [100.5, 1, 1]",
        ),
        ("[-1.0, 1.0, 1.0]", "[1.0, 1.0, 1.0]", "eta = [-1, 1, 1]"),
    ] {
        let e = conductor(eta, k).unwrap_err();
        assert!(
            e.contains("conductor eta and k must be >= 0 and at most 100") && e.contains(shown),
            "{e}"
        );
    }
}

/// Weights whose sum overflows (1e308 + 1e308) were refused as "the weights sum to zero": they
/// are read as the equal weights they are.
#[test]
fn weights_whose_sum_overflows_are_normalised() {
    let m = Material::from_toml_str(&format!(
        "[ndf]\nkind = \"phong-peaks\"\nlobes = [{{ axis = [0.0, 0.0], weight = 1e308, exponent = 10.0 }}, \
         {{ axis = [30.0, 0.0], weight = 1.5e308, exponent = 20.0 }}]\n{PHONG}"
    ))
    .unwrap();
    let Ndf::PhongPeaks(p) = &m.ndf else {
        panic!("kind")
    };
    let w: Vec<f64> = p.lobes().iter().map(|l| l.weight).collect();
    assert!(
        (w[0] - 0.4).abs() < 1e-12 && (w[1] - 0.6).abs() < 1e-12,
        "{w:?}"
    );
    let m = Material::from_toml_str(&format!(
        "[ndf]\nkind = \"mixture\"\nlobes = [{{ kind = \"ggx\", alpha = 0.2, weight = 1.7e308 }}, \
         {{ kind = \"beckmann\", alpha = 0.4, weight = 1.7e308 }}]\n{PHONG}"
    ))
    .unwrap();
    let Ndf::Mixture(x) = &m.ndf else {
        panic!("kind")
    };
    assert!(x.lobes().iter().all(|l| (l.weight - 0.5).abs() < 1e-12));
}

/// A radial NDF's angles are in degrees in the file, and so are its errors (they were in
/// radians: "the last angle 1.745329 rad is past the horizon").
#[test]
fn radial_angle_errors_are_in_degrees() {
    let radial = |theta: &str| {
        Material::from_toml_str(&format!(
            "[ndf]\nkind = \"radial\"\ntheta = {theta}\ndensity = [1.0, 0.5, 0.0]\n{PHONG}"
        ))
        .map_err(|e| e.to_string())
    };
    radial("[0.0, 45.0, 90.0]").unwrap();
    for (theta, want) in [
        (
            "[0.0, 45.0, 100.0]",
            "the last angle 100° is past the horizon (90°)",
        ),
        ("[5.0, 45.0, 90.0]", "the first angle must be 0, got 5°"),
        ("[0.0, 45.0, 30.0]", "node 2 is 30° after 45°"),
    ] {
        let e = radial(theta).unwrap_err();
        assert!(e.contains(want) && !e.contains(" rad "), "{e}");
    }
}

/// An absurd polar angle in a pairs file is written in exponent notation (it was 300 digits).
#[test]
fn pairs_errors_write_absurd_angles_short() {
    let e = meso_core::pairs::parse_pairs("theta_i,phi_i,theta_o,phi_o\n10,0,1e300,0\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("theta_o = 1e300 is outside [0, 90] degrees"),
        "{e}"
    );
    assert!(e.len() < 200, "{e}");
}
