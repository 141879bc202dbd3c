//! gensky and gendaylit skies: the distribution read from `skyfunc` shapes
//! the sky rays see, as skybright.cal and perezlum.cal compute it.

use glam::Vec3;

use super::*;
use crate::scene::material::Sky;
use crate::shade::sky::SkyModel;

/// What gensky 3 21 12 +s writes (sun due south at 49.9 degrees), with the
/// sky and ground glows every Radiance daylight scene adds.
const GENSKY: &str = "\
# gensky 3 21 12 +s
void light solar
0
0
3 6.38e+06 6.38e+06 6.38e+06

solar source sun
0
0
4 -0.000000 -0.644212 0.764848 0.5

void brightfunc skyfunc
2 skybr skybright.cal
0
7 1 3.56e+01 4.38e+01 2.41e-01 -0.000000 -0.644212 0.764848

skyfunc glow sky_mat
0
0
4 0.9 0.9 1.15 0

sky_mat source sky
0
0
4 0 0 1 180

skyfunc glow ground_glow
0
0
4 1 0.8 0.5 0

ground_glow source ground
0
0
4 0 0 -1 180
";

/// skybright.cal's CIE clear sky, written out here from the file's text.
fn clear_sky(d: [f64; 3]) -> f64 {
    let (a2, a3, a4) = (35.6, 43.8, 0.241);
    let sun = [0.0, -0.644212, 0.764848];
    let cosgamma: f64 = d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2];
    let gamma = cosgamma.clamp(-1.0, 1.0).acos();
    let horizon = if d[2] > 0.01 { 1.0 - (-0.32 / d[2]).exp() } else { 1.0 };
    let sunny = a2 * (0.91 + 10.0 * (-3.0 * gamma).exp() + 0.45 * cosgamma * cosgamma) * horizon / a4;
    let (a, b) = ((d[2] + 1.01f64).powi(10), (d[2] + 1.01f64).powi(-10));
    (a * sunny + b * a3) / (a + b)
}

#[test]
fn a_gensky_sky_shines_as_skybright_cal_says() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, report) = read(dir.path(), "sky.rad", GENSKY).unwrap();
    let Sky::Radiance { sky, ground, sun, .. } = &scene.sky else {
        panic!("{:?}", scene.sky)
    };
    assert_eq!((*sky, *ground), ([0.9, 0.9, 1.15], [1.0, 0.8, 0.5]));
    let sun = sun.as_ref().expect("the solar source is the sun");
    assert_eq!((sun.radiance, sun.diameter_deg), ([6.38e6; 3], 0.5));
    assert_eq!(report.count(NoteKind::GlowSky), 0, "{report:?}");
    let model = SkyModel::new(&scene.sky);
    for (name, d) in [
        ("zenith", Vec3::Z),
        ("horizon, south", Vec3::new(0.0, -0.9995, 0.03).normalize()),
        ("horizon, north", Vec3::new(0.0, 0.9995, 0.03).normalize()),
        ("circumsolar", Vec3::new(0.0, -0.7, 0.714).normalize()),
    ] {
        let want = clear_sky(d.as_dvec3().to_array()) as f32;
        let got = model.background(d);
        for (c, k) in [(0, 0.9f32), (1, 0.9), (2, 1.15)] {
            assert!(
                (got[c] - k * want).abs() <= 1e-4 * k * want,
                "{name}: channel {c} {} against skybright.cal's {}",
                got[c],
                k * want
            );
        }
    }
    // Below the horizon the ground glow's colour times the ground brightness.
    let down = model.background(-Vec3::Z);
    assert!(
        (down.x - 43.8).abs() < 0.05 && (down.z - 0.5 * 43.8).abs() < 0.05,
        "{down}"
    );
    // Straight up is far brighter than the uniform stand-in a glow alone made (0.9).
    assert!(model.background(Vec3::Z).x > 10.0);
}

#[test]
fn gendaylit_perez_skies_and_bad_sky_arguments() {
    let dir = tempfile::tempdir().unwrap();
    let perez = "\
void brightfunc skyfunc
2 skybright perezlum.cal
0
10 2.1e+01 3.2e+01 -1.0 -0.32 10.0 -3.0 0.45 0.0 -0.6 0.8
skyfunc glow sky_glow
0
0
4 1 1 1 0
sky_glow source sky
0
0
4 0 0 1 180
";
    let (scene, _) = read(dir.path(), "perez.rad", perez).unwrap();
    let model = SkyModel::new(&scene.sky);
    // perezlum.cal at the zenith: gamma is the sun's zenith angle.
    let gamma = 0.8f64.acos();
    let sky = 21.0 * (1.0 - (-0.32f64).exp()) * (1.0 + 10.0 * (-3.0 * gamma).exp() + 0.45 * gamma.cos() * gamma.cos());
    let (a, b) = (2.01f64.powi(10), 2.01f64.powi(-10));
    let want = ((a * sky + b * 32.0) / (a + b)) as f32;
    let got = model.background(Vec3::Z).x;
    assert!((got - want).abs() < 1e-4 * want, "{got} against perezlum.cal's {want}");
    let bad = GENSKY.replace("7 1 3.56e+01", "7 9 3.56e+01");
    let err = read(dir.path(), "bad.rad", &bad).unwrap_err();
    assert!(err.to_string().contains("sky type 9"), "{err}");
    let short = GENSKY.replace("7 1 3.56e+01 4.38e+01 2.41e-01", "4 1 3.56e+01 4.38e+01 2.41e-01");
    assert!(read(dir.path(), "short.rad", &short).is_err());
}
