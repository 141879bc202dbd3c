//! Materials, modifier chains and distant sources.

use glam::Vec3;

use super::*;

#[test]
fn materials_map_as_documented_and_approximations_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (s, report) = read(dir.path(), "everything.rad", EVERYTHING).unwrap();
    let Material::Plastic { albedo, roughness, ior } = material(&s, "red").clone() else {
        panic!("red is not plastic: {:?}", material(&s, "red"));
    };
    assert_eq!(albedo, [0.6, 0.1, 0.1]);
    assert!((roughness - 0.3).abs() < 1e-6, "roughness √0.09");
    assert!(
        (ior - 1.5).abs() < 1e-5,
        "spec 0.04 is the reflectance of ior 1.5: {ior}"
    );
    assert_eq!(material(&s, "m_sphere"), &Material::lambertian([0.5; 3]), "spec 0");
    assert_eq!(
        material(&s, "gold"),
        &Material::Metal {
            color: [0.9, 0.7, 0.3],
            roughness: 0.4
        }
    );
    assert!(
        matches!(material(&s, "shade"), Material::Plastic { albedo, .. } if *albedo == [0.4; 3]),
        "trans: opaque plastic of albedo rgb (1 - trans): {:?}",
        material(&s, "shade")
    );
    assert_eq!(
        material(&s, "pane"),
        &Material::Glass {
            ior: 1.52,
            color: [0.9; 3],
            thin: true
        }
    );
    assert!(matches!(material(&s, "thick"), Material::Glass { ior, thin: true, .. } if *ior == 1.4));
    assert_eq!(
        material(&s, "water"),
        &Material::Glass {
            ior: 1.33,
            color: [0.9, 0.95, 1.0],
            thin: false
        }
    );
    assert_eq!(material(&s, "silver"), &Material::Mirror { color: [0.95; 3] });
    assert_eq!(
        material(&s, "neon"),
        &Material::Emitter {
            radiance: [2.0, 3.0, 4.0]
        }
    );
    assert_eq!(material(&s, "spot"), &Material::Emitter { radiance: [100.0; 3] });
    // The illum shows its alternate material; without one, and with void,
    // the surfaces are left out.
    assert_eq!(triangles(&s, "pane").len(), 2, "p4 and the illum p9");
    assert!(!s.material_names.iter().any(|n| n == "window" || n == "ghost"));
    let zs: Vec<f32> = s.triangles.iter().map(|t| s.positions[t.v[0] as usize].z).collect();
    assert!(
        !zs.contains(&39.0) && !zs.contains(&40.0),
        "ghost and void polygons left out"
    );
    for kind in [
        NoteKind::TransOpaque,
        NoteKind::DielectricTint,
        NoteKind::MetalDiffuse,
        NoteKind::GlowRadius,
        NoteKind::SpotlightBeam,
        NoteKind::IllumAlternate,
        NoteKind::IllumInvisible,
        NoteKind::VoidSurface,
    ] {
        assert_eq!(report.count(kind), 1, "{kind:?} in {report:?}");
    }
    let void = report.notes.iter().find(|n| n.kind == NoteKind::VoidSurface).unwrap();
    assert_eq!(void.first.line, 44, "{void:?}");
    assert!(void.detail.contains("p11"));
    // The distant light is the sun, its radiance unchanged.
    let h = std::f32::consts::FRAC_1_SQRT_2;
    match &s.sky {
        Sky::Sun {
            direction,
            sun_radiance,
            diameter_deg,
            zenith,
            ..
        } => {
            assert!(Vec3::from(*direction).abs_diff_eq(Vec3::new(0.0, h, h), 1e-6));
            assert_eq!(*sun_radiance, [1e5; 3]);
            assert_eq!(*diameter_deg, 0.53);
            assert_eq!(*zenith, [0.0; 3]);
        }
        other => panic!("no sun: {other:?}"),
    }
}

#[test]
fn modifier_chains_resolve_by_the_latest_definition() {
    let dir = tempfile::tempdir().unwrap();
    let text = "\
void brightfunc dirt 2 dirt dirt.cal 0 0
dirt plastic stained 0 0 5 .7 .6 .5 0 0
stained polygon a 0 0 9 0 0 0 1 0 0 0 1 0
void plastic paint 0 0 5 .1 .1 .1 0 0
paint polygon b 0 0 9 0 0 1 1 0 1 0 1 1
void plastic paint 0 0 5 .9 .9 .9 0 0
paint polygon c 0 0 9 0 0 2 1 0 2 0 1 2
void alias paint2 paint
paint2 polygon d 0 0 9 0 0 3 1 0 3 0 1 3
stained colorpict pic 7 red green blue img.hdr picture.cal pic_u pic_v 0 0
pic polygon e 0 0 9 0 0 4 1 0 4 0 1 4
void mixfunc mix 4 stained paint mixval mix.cal 0 0
mix polygon f 0 0 9 0 0 5 1 0 5 0 1 5
";
    let (s, report) = read(dir.path(), "chains.rad", text).unwrap();
    let material_at = |z: f32| {
        let t = s
            .triangles
            .iter()
            .find(|t| s.positions[t.v[0] as usize].z == z)
            .unwrap();
        (
            s.material_names[t.material as usize].as_str(),
            &s.materials[t.material as usize],
        )
    };
    assert_eq!(
        material_at(0.0),
        ("stained", &Material::lambertian([0.7, 0.6, 0.5])),
        "a pattern on the chain leaves the base color"
    );
    assert_eq!(material_at(1.0), ("paint", &Material::lambertian([0.1; 3])));
    assert_eq!(
        material_at(2.0),
        ("paint#2", &Material::lambertian([0.9; 3])),
        "a redefined name takes its new definition from then on"
    );
    assert_eq!(material_at(3.0).0, "paint#2", "an alias is its target");
    assert_eq!(material_at(4.0).0, "stained", "surface -> pattern -> material");
    assert_eq!(material_at(5.0).0, "stained", "a mixture shows its foreground");
    assert_eq!(
        report.count(NoteKind::PatternIgnored),
        1,
        "the brightfunc; the colorpict pictures"
    );
    assert!(
        s.notes.iter().any(|n| n.what.contains("img.hdr")),
        "its picture is missing: {:?}",
        s.notes
    );
    assert_eq!(report.count(NoteKind::MixtureForeground), 1);
    let first = &report.notes[0];
    assert_eq!((first.kind, first.first.line), (NoteKind::PatternIgnored, 1));

    let e = rad_error(
        dir.path(),
        "undefined.rad",
        "void plastic m 0 0 5 .5 .5 .5 0 0\n\nnothing polygon x 0 0 9 0 0 0 1 0 0 0 1 0\n",
    );
    assert_eq!(e.at.line, 3);
    assert!(matches!(&*e.kind, RadErrorKind::UndefinedModifier { name } if name == "nothing"));
    assert!(e.to_string().contains("undefined.rad:3:"), "{e}");
    // A surface may not use a name that was only a surface.
    let e = rad_error(
        dir.path(),
        "surface_name.rad",
        "void plastic m 0 0 5 .5 .5 .5 0 0\nm polygon x 0 0 9 0 0 0 1 0 0 0 1 0\nx polygon y 0 0 9 0 0 0 1 0 0 0 1 0\n",
    );
    assert!(matches!(*e.kind, RadErrorKind::UndefinedModifier { .. }) && e.at.line == 3);
}

#[test]
fn glow_sources_become_the_sky_and_numbers_read_as_radiance_writes_them() {
    let dir = tempfile::tempdir().unwrap();
    let text = "\
void brightfunc skyfunc 2 skybr skybright.cal 0 7 1 3.2 5.1 .8 .2 .5 .1
skyfunc glow skyglow 0 0 4 .9 .9 1.1 0
skyglow source sky 0 0 4 0 0 1 180
void glow groundglow 0 0 4 .2 .18 .15 0
groundglow source ground 0 0 4 0 0 -1 180
void plastic m 0 0 5 +.5 5e-1 .5 0. 0
m polygon p 0 0 9 0 0 0 1 0 0 0 1 0
";
    let (s, report) = read(dir.path(), "sky.rad", text).unwrap();
    match &s.sky {
        Sky::Radiance {
            sky,
            ground,
            sky_shaped,
            ground_shaped,
            sun,
            ..
        } => {
            assert_eq!((*sky, *sky_shaped), ([0.9, 0.9, 1.1], true));
            assert_eq!(
                (*ground, *ground_shaped),
                ([0.2, 0.18, 0.15], false),
                "its glow has no skyfunc"
            );
            assert_eq!(*sun, None);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(report.count(NoteKind::GlowSky), 1, "the ground glow alone is uniform");
    let model = crate::shade::sky::SkyModel::new(&s.sky);
    assert_eq!(model.background(-glam::Vec3::Z), glam::Vec3::new(0.2, 0.18, 0.15));
    assert_eq!(material(&s, "m"), &Material::lambertian([0.5; 3]));
}
