//! Radiance function files (`.cal`) and data files (seed the corpus with
//! real ones): reading fails with an error or gives definitions whose
//! every name compiles or is refused, and whose evaluation gives a number
//! or a fault, never a panic, a hang or a stack overflow.
#![no_main]

use holodeck_sampler::scene::calc::data::Table;
use holodeck_sampler::scene::calc::parse::{definitions, Expr};
use holodeck_sampler::scene::calc::program::{Compiler, Eval};
use holodeck_sampler::scene::calc::RayVars;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(table) = Table::parse(text, "fuzz.dat") {
        for at in [[0.0, 0.0], [1e9, -1e9], [0.5, 7.0]] {
            let _ = table.value(&at);
        }
    }
    let Ok(defs) = definitions(text, "fuzz.cal") else { return };
    let mut vars = RayVars::default();
    for (k, v) in vars.0.iter_mut().enumerate() {
        *v = k as f64 * 0.37 - 2.0;
    }
    for d in defs.iter().take(64) {
        let mut c = Compiler::new(&defs, "fuzz.cal");
        let call = if d.params.is_empty() {
            Expr::Name(d.name.clone())
        } else {
            Expr::Call(d.name.clone(), d.params.iter().map(|_| Expr::Num(0.5)).collect())
        };
        let Ok(root) = c.root(&call) else { continue };
        let program = c.finish();
        let _ = Eval::new(&program, &vars, &[1.0, 2.0]).value(root);
    }
});
