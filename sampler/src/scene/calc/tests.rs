//! The calc language read and evaluated as Radiance reads it, checked on
//! values worked out by hand.

use super::data::Table;
use super::parse::{definitions, expression};
use super::program::{Compiler, Eval, Fault};
use super::{RayVars, Var};

/// The value of `expr` with the definitions `file`, rays `vars` and real arguments `args`.
fn eval_with(file: &str, expr: &str, vars: &RayVars, args: &[f64]) -> Result<f64, Fault> {
    let defs = definitions(file, "test.cal").unwrap();
    let mut c = Compiler::new(&defs, "test.cal");
    let root = c.root(&expression(expr, "expr").unwrap()).unwrap();
    let program = c.finish();
    let value = Eval::new(&program, vars, args).value(root);
    value
}

fn eval(file: &str, expr: &str) -> f64 {
    eval_with(file, expr, &RayVars::default(), &[]).unwrap()
}

#[test]
fn operators_bind_as_radiance_binds_them() {
    assert_eq!(eval("", "-2^2"), 4.0, "unary minus binds tighter than ^");
    assert_eq!(eval("", "2^3^2"), 512.0, "^ is right-associative");
    assert_eq!(eval("", "2^-2"), 0.25);
    assert_eq!(eval("", "-2*-3"), 6.0);
    assert_eq!(eval("", "1 - 2 - 3"), -4.0);
    assert_eq!(eval("", "8 / 4 / 2"), 1.0);
    assert_eq!(eval("", "1 + 2 * 3 ^ 2"), 19.0);
    assert_eq!(eval("", ".5 + 5. + 1e1 + 2.5E-1"), 15.75);
}

#[test]
fn definitions_functions_comments_and_passing_functions() {
    let file = "
        { a comment { nested } still a comment }
        k : 3;
        sqr(x) = x * x;
        f(g, x) = g(x) * 2;
        h(x) = x + 1;
        twice = f(h, k);
        fact(n) = if(n - .5, n * fact(n - 1), 1)
    ";
    assert_eq!(eval(file, "twice"), 8.0);
    assert_eq!(eval(file, "sqr(k) + k"), 12.0);
    assert_eq!(eval(file, "fact(5)"), 120.0, "recursion ends through if");
    assert_eq!(eval(file, "select(0, 7, 8, 9)"), 3.0);
    assert_eq!(eval(file, "select(2, 7, 8, 9)"), 8.0);
    assert_eq!(eval(file, "max(1, 5, 3) - min(4, 2, 9)"), 3.0);
    assert!(
        (eval("", "rand(1)") - 0.350_083_059_8).abs() < 1e-9,
        "{}",
        eval("", "rand(1)")
    );
}

#[test]
fn the_start_up_names_mean_what_radiance_defines() {
    let mut v = RayVars::default();
    for (var, x) in [
        (Var::Dx, 0.6),
        (Var::Dy, 0.0),
        (Var::Dz, -0.8),
        (Var::Nx, 0.0),
        (Var::Ny, 0.0),
        (Var::Nz, 1.0),
    ] {
        v.set(var, x);
    }
    let e = |s: &str| eval_with("", s, &v, &[2.0, 5.0]).unwrap();
    assert_eq!(e("dot(D, N)"), -0.8);
    assert_eq!(e("cross(2, D, N)"), -0.6, "(D × N)y = Dz·Nx − Dx·Nz");
    assert_eq!(e("AC + A1 * A2"), 12.0);
    assert_eq!(e("bound(0, 1.5, 1) + abs(-2) + sgn(-3) + sq(3)"), 11.0);
    assert_eq!(e("and(1, 0) + or(0, 2) + not(1)"), 1.0);
    assert_eq!(e("mod(7, 3) + frac(2.25)"), 1.25);
    assert_eq!(e("tri(2.5, 1)"), 0.5);
    assert_eq!(e("linterp(.25, 4, 8)"), 5.0);
    assert!((e("PI * DEGREE * 180 / PI") - std::f64::consts::PI).abs() < 1e-12);
    // A shadow ray heading down and along +x toward a light below: the
    // light sends it up toward -x, 143.13 degrees from its nadir.
    assert!(
        (e("src_theta") - (-0.8f64).acos().to_degrees()).abs() < 1e-9,
        "{}",
        e("src_theta")
    );
    assert!(
        (e("src_phi") - 180.0).abs() < 1e-9,
        "emitted toward -x: {}",
        e("src_phi")
    );
    assert!((e("src_phi4") - 0.0).abs() < 1e-9);
    // An arithmetic fault fails the evaluation instead of giving a number.
    assert_eq!(eval_with("", "1 / (A1 - 2)", &v, &[2.0]), Err(Fault::Arithmetic));
    assert_eq!(
        eval_with("", "A3", &v, &[2.0]),
        Err(Fault::Arithmetic),
        "a missing real argument"
    );
}

#[test]
fn runaway_recursion_fails_instead_of_overflowing() {
    assert_eq!(
        eval_with("f(x) = f(x + 1) + 1;", "f(0)", &RayVars::default(), &[]),
        Err(Fault::Budget)
    );
    assert_eq!(
        eval_with("g(x) = g(x) + g(x);", "g(0)", &RayVars::default(), &[]),
        Err(Fault::Budget)
    );
}

#[test]
fn bad_text_is_refused_with_its_line() {
    let e = definitions("a = 1;\nb = (2 + ;\n", "bad.cal").unwrap_err();
    assert!(e.to_string().contains("bad.cal, line 2"), "{e}");
    let e = definitions("a = 1; { open\n", "open.cal").unwrap_err();
    assert!(e.to_string().contains("never closed"), "{e}");
    let e = definitions("a = 1e+;", "exp.cal").unwrap_err();
    assert!(e.to_string().contains("exponent"), "{e}");
    let deep = format!("a = {}1{};", "(".repeat(500), ")".repeat(500));
    assert!(definitions(&deep, "deep.cal").is_err());
    let defs = definitions("a = nothing_here;", "undefined.cal").unwrap();
    let mut c = Compiler::new(&defs, "undefined.cal");
    let e = c.root(&expression("a", "expr").unwrap()).unwrap_err();
    assert!(e.to_string().contains("\"nothing_here\""), "{e}");
}

#[test]
fn data_tables_interpolate_and_fade_as_radiance_reads_them() {
    // 2 x 3: rows at x = 0, 10; columns listed at y = 0, 1, 4.
    let t = Table::parse("# a comment\n2\n0 10 2\n0 0 3 0 1 4\n1 2 3\n11 12 13\n", "t.dat").unwrap();
    assert_eq!(t.value(&[0.0, 0.0]), 1.0);
    assert_eq!(t.value(&[10.0, 4.0]), 13.0);
    assert!((t.value(&[5.0, 0.5]) - 6.5).abs() < 1e-9);
    assert!((t.value(&[5.0, 2.5]) - 7.5).abs() < 1e-9);
    // One cell past the end extrapolates linearly.
    assert!((t.value(&[15.0, 0.0]) - 16.0).abs() < 1e-9);
    // Further, it fades toward zero.
    assert!(t.value(&[1000.0, 0.0]).abs() < 1.0);
    for bad in ["", "7\n", "1\n0 1 1\n5", "1\n0 0 3 0 2 1\n1 2 3", "1\n0 1 2\n1 x"] {
        assert!(Table::parse(bad, "bad.dat").is_err(), "{bad:?}");
    }
}
