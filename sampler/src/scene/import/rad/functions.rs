//! Radiance's function and data patterns read from their files:
//! `colorfunc`, `brightfunc`, `texfunc`, `brightdata` and `colordata`,
//! their function files (`.cal`) and data files found beside the file that
//! names them or on `RAYPATH`, parsed once each, and the expressions their
//! arguments give compiled against them. Radiance's own library files
//! (`rayinit.cal`, `source.cal`, `tilt.cal`) need not be present: their
//! names are natives here.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use glam::DMat4;

use super::parse::Primitive;
use crate::scene::calc::data::Table;
use crate::scene::calc::parse::{definitions, expression, Definition};
use crate::scene::calc::program::{Callee, Compiler};
use crate::scene::pattern::{Pattern, PatternKind};

/// Largest function or data file read.
const MAX_BYTES: u64 = 64 << 20;

/// Library files whose names are natives: used when not found on disk.
const LIBRARY: [&str; 3] = ["rayinit.cal", "source.cal", "tilt.cal"];

/// The function and data files read so far.
#[derive(Default)]
pub(super) struct FunctionFiles {
    functions: HashMap<PathBuf, Rc<Vec<Definition>>>,
    tables: HashMap<PathBuf, Rc<Table>>,
}

/// Whether `kind` is a pattern this module reads.
pub(super) fn is_function_pattern(kind: &str) -> bool {
    matches!(
        kind,
        "colorfunc" | "brightfunc" | "texfunc" | "brightdata" | "colordata"
    )
}

impl FunctionFiles {
    /// The pattern `p` defines (its file named relative to `dir`, the file
    /// placed by `placed`), or why it cannot be used.
    pub(super) fn pattern(&mut self, p: &Primitive, dir: &Path, placed: &DMat4) -> Result<Pattern, String> {
        let s = &p.strings;
        let need = |n: usize, layout: &str| {
            if s.len() < n {
                Err(format!("needs {n} or more strings: {layout}"))
            } else {
                Ok(())
            }
        };
        // (expressions, function file, data files, named functions, what follows)
        let (exprs, file, data, funcs, rest): (&[String], &str, &[String], &[String], usize) = match p.kind.as_str() {
            "colorfunc" => {
                need(4, "red green blue funcfile [transform]")?;
                (&s[0..3], &s[3], &[], &[], 4)
            }
            "brightfunc" => {
                need(2, "refl funcfile [transform]")?;
                (&s[0..1], &s[1], &[], &[], 2)
            }
            "texfunc" => {
                need(4, "xpert ypert zpert funcfile [transform]")?;
                (&s[0..3], &s[3], &[], &[], 4)
            }
            "brightdata" => {
                need(4, "func datafile funcfile x1 ... [transform]")?;
                (&[], &s[2], &s[1..2], &s[0..1], 3)
            }
            "colordata" => {
                need(
                    8,
                    "rfunc gfunc bfunc rdatafile gdatafile bdatafile funcfile x1 ... [transform]",
                )?;
                (&[], &s[6], &s[3..6], &s[0..3], 7)
            }
            other => return Err(format!("{other} patterns are not read")),
        };
        let defs = self.functions(file, dir)?;
        let what = file.to_string();
        let tables = data.iter().map(|d| self.table(d, dir)).collect::<Result<Vec<_>, _>>()?;
        let dims = tables.first().map_or(0, |t| t.axes.len());
        if tables.iter().any(|t| t.axes.len() != dims) {
            return Err("its data files have different numbers of dimensions".to_string());
        }
        if s.len() < rest + dims {
            return Err(format!(
                "its data file has {dims} dimensions but {} coordinate expressions follow",
                s.len() - rest
            ));
        }
        let coords = &s[rest..rest + dims];
        // The transform starts at the first option; words before it are ignored.
        let after = &s[rest + dims..];
        let start = after.iter().position(|w| w.starts_with('-')).unwrap_or(after.len());
        let transform = super::command::transform_args(&after[start..]).map_err(|e| e.to_string())?;
        let to_pattern = (*placed * transform).inverse();
        if !to_pattern.is_finite() {
            return Err("its transform cannot be inverted".to_string());
        }
        let mut c = Compiler::new(&defs, &what);
        let mut root = |text: &str| -> Result<u32, String> {
            let e = expression(text, &format!("argument {text:?}")).map_err(|e| e.to_string())?;
            c.root(&e).map_err(|e| e.to_string())
        };
        let roots = exprs.iter().map(|e| root(e)).collect::<Result<Vec<_>, _>>()?;
        let coords = coords.iter().map(|e| root(e)).collect::<Result<Vec<_>, _>>()?;
        let named = funcs
            .iter()
            .map(|f| c.function(f).map_err(|e| e.to_string()))
            .collect::<Result<Vec<Callee>, _>>()?;
        let kind = match p.kind.as_str() {
            "colorfunc" => PatternKind::Color([roots[0], roots[1], roots[2]]),
            "brightfunc" => PatternKind::Bright(roots[0]),
            "texfunc" => PatternKind::Normal([roots[0], roots[1], roots[2]]),
            "brightdata" => PatternKind::BrightData {
                func: named[0],
                table: (*tables[0]).clone(),
                coords,
            },
            _ => {
                // Red's function sees (r, g, b); green's and blue's see their
                // own value unless they take three.
                let takes_three = |f: &str| {
                    defs.iter()
                        .rev()
                        .find(|d| d.name == f)
                        .is_some_and(|d| d.params.len() >= 3)
                };
                PatternKind::ColorData {
                    funcs: [
                        (named[0], true),
                        (named[1], takes_three(&funcs[1])),
                        (named[2], takes_three(&funcs[2])),
                    ],
                    tables: Box::new([(*tables[0]).clone(), (*tables[1]).clone(), (*tables[2]).clone()]),
                    coords,
                }
            }
        };
        Ok(Pattern::new(
            p.name.clone(),
            kind,
            c.finish(),
            p.reals.clone(),
            to_pattern,
        ))
    }

    /// The definitions of function file `name` (`.` for none).
    fn functions(&mut self, name: &str, dir: &Path) -> Result<Rc<Vec<Definition>>, String> {
        if name == "." {
            return Ok(Rc::default());
        }
        let Some(path) = find(name, dir) else {
            let base = name.rsplit(['/', '\\']).next().unwrap_or(name);
            if LIBRARY.contains(&base) {
                return Ok(Rc::default());
            }
            return Err(format!(
                "function file {name} is not in {} or on RAYPATH",
                dir.display()
            ));
        };
        if let Some(d) = self.functions.get(&path) {
            return Ok(d.clone());
        }
        let text = read(&path)?;
        let defs = Rc::new(definitions(&text, &path.display().to_string()).map_err(|e| e.to_string())?);
        self.functions.insert(path, defs.clone());
        Ok(defs)
    }

    /// The table of data file `name`.
    fn table(&mut self, name: &str, dir: &Path) -> Result<Rc<Table>, String> {
        let path =
            find(name, dir).ok_or_else(|| format!("data file {name} is not in {} or on RAYPATH", dir.display()))?;
        if let Some(t) = self.tables.get(&path) {
            return Ok(t.clone());
        }
        let text = read(&path)?;
        let table = Rc::new(Table::parse(&text, &path.display().to_string()).map_err(|e| e.to_string())?);
        self.tables.insert(path, table.clone());
        Ok(table)
    }
}

/// `name` beside the file that names it (`dir`), or in a `RAYPATH` directory.
fn find(name: &str, dir: &Path) -> Option<PathBuf> {
    let given = Path::new(name);
    if given.is_absolute() {
        return given.is_file().then(|| given.to_path_buf());
    }
    let here = dir.join(given);
    if here.is_file() {
        return Some(here);
    }
    let raypath = std::env::var_os("RAYPATH")?;
    std::env::split_paths(&raypath)
        .map(|d| d.join(given))
        .find(|p| p.is_file())
}

/// The text of `path`, refused past [`MAX_BYTES`].
fn read(path: &Path) -> Result<String, String> {
    let meta = std::fs::metadata(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if !meta.is_file() || meta.len() > MAX_BYTES {
        return Err(format!(
            "{}: not a regular file of at most {MAX_BYTES} bytes",
            path.display()
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    String::from_utf8(bytes).map_err(|_| format!("{}: not text", path.display()))
}
