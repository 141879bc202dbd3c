//! Bad input: errors naming the line, never a panic.

use super::*;

#[test]
fn bad_input_is_an_error_naming_the_line_never_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let m = "void plastic m 0 0 5 .5 .5 .5 0 0\n";
    // The text, the line the error names, and what kind of error it is.
    type Case = (String, u32, fn(&RadErrorKind) -> bool);
    let cases: Vec<Case> = vec![
        ("void plastic m 0 0 5 1 1\n".into(), 2, |k| {
            matches!(k, RadErrorKind::Truncated { .. })
        }),
        (
            "void plastic m 0 0 5 1 x 1 1 1".into(),
            1,
            |k| matches!(k, RadErrorKind::NotANumber { token, .. } if token == "x"),
        ),
        ("void plastic m 0 0 5 nan 1 1 1 1".into(), 1, |k| {
            matches!(k, RadErrorKind::NotANumber { .. })
        }),
        ("void plastic m 0 0 5 1e999 1 1 1 1".into(), 1, |k| {
            matches!(k, RadErrorKind::NotANumber { .. })
        }),
        ("void plastic m 0 0\n99999999999999 1".into(), 2, |k| {
            matches!(k, RadErrorKind::TooManyArguments { group: "real", .. })
        }),
        ("void plastic m 0 0 -3".into(), 1, |k| {
            matches!(k, RadErrorKind::BadCount { .. })
        }),
        ("void plastic m 0 1 1.5 0".into(), 1, |k| {
            matches!(k, RadErrorKind::NotAnInteger { .. })
        }),
        ("void plastic m 0 0 4 1 1 1 1".into(), 1, |k| {
            matches!(k, RadErrorKind::ArgumentCount { .. })
        }),
        (format!("{m}m polygon p 0 0 6 0 0 0 1 0 0"), 2, |k| {
            matches!(k, RadErrorKind::ArgumentCount { .. })
        }),
        (format!("{m}m sphere s 0 0 4 0 0 0 0"), 2, |k| {
            matches!(k, RadErrorKind::BadArguments { .. })
        }),
        (format!("{m}m cone c 0 0 8 0 0 0 0 0 1 1 -1"), 2, |k| {
            matches!(k, RadErrorKind::BadArguments { .. })
        }),
        (format!("{m}m ring r 0 0 8 0 0 0 0 0 0 0 1"), 2, |k| {
            matches!(k, RadErrorKind::BadArguments { .. })
        }),
        (format!("{m}m cylinder c 0 0 7 1 1 1 1 1 1 1"), 2, |k| {
            matches!(k, RadErrorKind::BadArguments { .. })
        }),
        (format!("{m}m source s 0 0 3 0 0 1"), 2, |k| {
            matches!(k, RadErrorKind::ArgumentCount { .. })
        }),
        ("void glass g 0 0 4 1 1 1 0.5".into(), 1, |k| {
            matches!(k, RadErrorKind::BadArguments { .. })
        }),
        ("void foo x 0 0 0".into(), 1, |k| {
            matches!(k, RadErrorKind::UnknownType { .. })
        }),
        ("void plastic void 0 0 5 1 1 1 0 0".into(), 1, |k| {
            matches!(k, RadErrorKind::ReservedName { .. })
        }),
        (format!("{m}m instance i 1 chair.oct 0 0"), 2, |k| {
            matches!(k, RadErrorKind::UnsupportedSurface { .. })
        }),
        (
            "void BRTDfunc b 10 0 0 0 0 0 0 0 0 0 . 0 9 0 0 0 0 0 0 0 0 0\nb polygon p 0 0 9 0 0 0 1 0 0 0 1 0".into(),
            2,
            |k| matches!(k, RadErrorKind::UnsupportedMaterial { kind, .. } if kind == "BRTDfunc"),
        ),
        ("void plastic \"unterminated 0 0 5 1 1 1 0 0".into(), 1, |k| {
            matches!(k, RadErrorKind::Truncated { .. })
        }),
        ("void plastic".into(), 1, |k| {
            matches!(k, RadErrorKind::Truncated { .. })
        }),
        (
            format!("{m}m plastic x 0 0 5 1 1 1 0 0\nm source s 0 0 4 0 0 1 1"),
            3,
            |k| matches!(k, RadErrorKind::Source { .. }),
        ),
        (format!("{m}!genbox m b 1 0 1"), 2, |k| {
            matches!(k, RadErrorKind::BadCommand { .. })
        }),
        (format!("{m}!xform -t 1 x 0 f.rad"), 2, |k| {
            matches!(k, RadErrorKind::BadCommand { .. })
        }),
        (format!("{m}!xform -i 99999999999 f.rad"), 2, |k| {
            matches!(k, RadErrorKind::BadCommand { .. })
        }),
    ];
    for (k, (text, line, want)) in cases.iter().enumerate() {
        let name = format!("bad{k}.rad");
        let e = rad_error(dir.path(), &name, text);
        assert!(want(&e.kind), "{name} {text:?}: {e}");
        assert_eq!(e.at.line, *line, "{name} {text:?}: {e}");
        assert!(e.to_string().contains(&format!("{name}:{line}: ")), "{e}");
    }
    // A word without end is refused rather than collected.
    let e = rad_error(dir.path(), "long.rad", &"x".repeat(lexer::MAX_WORD + 10));
    assert!(matches!(*e.kind, RadErrorKind::WordTooLong { .. }));
    // Two suns.
    let text = "void light sun 0 0 3 1 1 1\nsun source a 0 0 4 0 0 1 .5\nsun source b 0 0 4 0 1 1 .5\n";
    let e = rad_error(dir.path(), "suns.rad", text);
    assert!(matches!(*e.kind, RadErrorKind::Source { .. }) && e.at.line == 3, "{e}");
}

#[test]
fn random_token_soup_never_panics() {
    use proptest::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let words = [
        "void",
        "m",
        "plastic",
        "polygon",
        "sphere",
        "ring",
        "cone",
        "source",
        "light",
        "glow",
        "illum",
        "alias",
        "brightfunc",
        "mixfunc",
        "0",
        "1",
        "3",
        "4",
        "5",
        "9",
        "-1",
        "1e308",
        "x",
        "#",
        "\n",
        "!xform",
        "!genbox",
        "-t",
        "-i",
        "\"",
        "m.rad",
        "!xform -I soup.rad",
    ];
    let mut runner = proptest::test_runner::TestRunner::new(proptest::test_runner::Config {
        cases: 200,
        ..Default::default()
    });
    let strategy = proptest::collection::vec(0..words.len(), 0..60);
    runner
        .run(&strategy, |picks| {
            let text: Vec<&str> = picks.iter().map(|&k| words[k]).collect();
            let _ = read(dir.path(), "soup.rad", &text.join(" "));
            prop_assert!(true);
            Ok(())
        })
        .unwrap();
}
