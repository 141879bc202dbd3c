//! A function file compiled for evaluation: every name resolved once (a
//! parameter, a definition of the file, a native, a ray variable), the
//! definitions a pattern reaches laid out in one array, and evaluation
//! with Radiance's rules: `if` and `select` evaluate only the branch they
//! take, a division by zero or a result that is not a number gives 0 and
//! marks the evaluation as failed, and a budget of steps and depth stops
//! runaway recursion.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use super::builtin::{self, Builtin};
use super::parse::{Definition, Expr, Op};
use super::{CalcError, RayVars, Var};

/// Most nodes one evaluation may visit.
const MAX_STEPS: u32 = 200_000;
/// Deepest call nesting of one evaluation.
const MAX_DEPTH: u32 = 256;

/// What a function argument can be: a function named by the caller.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Callee {
    /// A definition of the file (index into the program's functions).
    User(u32),
    /// A native.
    Native(Builtin),
}

/// One compiled node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
enum Node {
    Num(f64),
    Var(Var),
    Param(u16),
    Call(Callee, Vec<u32>),
    CallParam(u16, Vec<u32>),
    Func(Callee),
    Neg(u32),
    Bin(u8, u32, u32),
}

/// A compiled definition.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Function {
    name: String,
    params: u16,
    body: u32,
}

/// Compiled expressions and the definitions they reach.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Program {
    nodes: Vec<Node>,
    functions: Vec<Function>,
}

/// A value on the evaluation stack.
#[derive(Clone, Copy, Debug)]
pub enum Value {
    /// A number.
    Num(f64),
    /// A function passed by name.
    Func(Callee),
}

/// Compiles expressions against the definitions of one file.
pub struct Compiler<'a> {
    defs: HashMap<&'a str, &'a Definition>,
    what: String,
    program: Program,
    compiled: HashMap<String, u32>,
}

impl<'a> Compiler<'a> {
    /// A compiler over `defs` (later definitions of a name replace earlier
    /// ones); `what` names the file in errors.
    pub fn new(defs: &'a [Definition], what: &str) -> Compiler<'a> {
        Compiler {
            defs: defs.iter().map(|d| (d.name.as_str(), d)).collect(),
            what: what.to_string(),
            program: Program::default(),
            compiled: HashMap::new(),
        }
    }

    /// Whether the file defines a function (with parameters) named `name`.
    pub fn function(&mut self, name: &str) -> Result<Callee, CalcError> {
        if let Some(d) = self.defs.get(name).copied() {
            if d.params.is_empty() {
                return Err(self.undefined(name, "a function of one or more arguments"));
            }
            return Ok(Callee::User(self.define(d)?));
        }
        match builtin::named(name) {
            Some(b) if !builtin::is_value(b) => Ok(Callee::Native(b)),
            _ => Err(self.undefined(name, "a function")),
        }
    }

    /// Compiles `e` (in no function: it has no parameters) and returns its root.
    pub fn root(&mut self, e: &Expr) -> Result<u32, CalcError> {
        self.expr(e, &[])
    }

    /// The compiled program.
    pub fn finish(self) -> Program {
        self.program
    }

    fn undefined(&self, name: &str, wanted: &str) -> CalcError {
        CalcError::Undefined {
            what: self.what.clone(),
            name: name.to_string(),
            wanted: wanted.to_string(),
        }
    }

    fn push(&mut self, n: Node) -> u32 {
        self.program.nodes.push(n);
        (self.program.nodes.len() - 1) as u32
    }

    /// The function index of definition `d`, compiling it the first time.
    fn define(&mut self, d: &'a Definition) -> Result<u32, CalcError> {
        if let Some(&i) = self.compiled.get(&d.name) {
            return Ok(i);
        }
        let index = self.program.functions.len() as u32;
        if d.params.len() > u16::MAX as usize {
            return Err(self.undefined(&d.name, "fewer parameters"));
        }
        self.program.functions.push(Function {
            name: d.name.clone(),
            params: d.params.len() as u16,
            body: 0,
        });
        self.compiled.insert(d.name.clone(), index);
        let params: Vec<&str> = d.params.iter().map(String::as_str).collect();
        let body = self.expr(&d.body, &params)?;
        self.program.functions[index as usize].body = body;
        Ok(index)
    }

    fn expr(&mut self, e: &Expr, params: &[&str]) -> Result<u32, CalcError> {
        Ok(match e {
            Expr::Num(v) => self.push(Node::Num(*v)),
            Expr::Neg(a) => {
                let a = self.expr(a, params)?;
                self.push(Node::Neg(a))
            }
            Expr::Bin(op, a, b) => {
                let (a, b) = (self.expr(a, params)?, self.expr(b, params)?);
                let op = match op {
                    Op::Add => 0,
                    Op::Sub => 1,
                    Op::Mul => 2,
                    Op::Div => 3,
                    Op::Pow => 4,
                };
                self.push(Node::Bin(op, a, b))
            }
            Expr::Name(name) => self.name(name, params)?,
            Expr::Call(name, args) => {
                let args = args
                    .iter()
                    .map(|a| self.expr(a, params))
                    .collect::<Result<Vec<_>, _>>()?;
                if let Some(i) = params.iter().position(|p| p == name) {
                    return Ok(self.push(Node::CallParam(i as u16, args)));
                }
                if let Some(d) = self.defs.get(name.as_str()).copied() {
                    let f = self.define(d)?;
                    return Ok(self.push(Node::Call(Callee::User(f), args)));
                }
                match builtin::named(name) {
                    Some(b) if !builtin::is_value(b) => self.push(Node::Call(Callee::Native(b), args)),
                    _ => return Err(self.undefined(name, "a function")),
                }
            }
        })
    }

    /// A name written without arguments.
    fn name(&mut self, name: &str, params: &[&str]) -> Result<u32, CalcError> {
        if let Some(i) = params.iter().position(|p| *p == name) {
            return Ok(self.push(Node::Param(i as u16)));
        }
        if let Some(d) = self.defs.get(name).copied() {
            let f = self.define(d)?;
            // A function with parameters named bare is passed as a function.
            return Ok(if d.params.is_empty() {
                self.push(Node::Call(Callee::User(f), Vec::new()))
            } else {
                self.push(Node::Func(Callee::User(f)))
            });
        }
        if let Some(v) = Var::named(name) {
            return Ok(self.push(Node::Var(v)));
        }
        if let Some(k) = name.strip_prefix('A').and_then(|k| k.parse::<u32>().ok()) {
            let n = self.push(Node::Num(f64::from(k)));
            return Ok(self.push(Node::Call(Callee::Native(Builtin::Arg), vec![n])));
        }
        if name == "AC" {
            let n = self.push(Node::Num(0.0));
            return Ok(self.push(Node::Call(Callee::Native(Builtin::Arg), vec![n])));
        }
        match builtin::named(name) {
            Some(b) if builtin::is_value(b) => Ok(self.push(Node::Call(Callee::Native(b), Vec::new()))),
            Some(b) => Ok(self.push(Node::Func(Callee::Native(b)))),
            None => Err(self.undefined(name, "a variable")),
        }
    }
}

/// Why an evaluation failed (its pattern then leaves the surface as it is).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// A division by zero, a power or function that is not a number, a
    /// missing argument or real argument.
    Arithmetic,
    /// Too many steps or too deep a recursion.
    Budget,
}

thread_local! {
    /// Evaluation stacks kept for the next evaluation on this thread: one
    /// runs at every hit of a patterned surface, and need not allocate.
    static STACKS: std::cell::RefCell<Vec<Vec<Value>>> = const { std::cell::RefCell::new(Vec::new()) };
}

impl Drop for Eval<'_> {
    fn drop(&mut self) {
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        STACKS.with(|s| s.borrow_mut().push(stack));
    }
}

/// One evaluation's state.
pub struct Eval<'p> {
    program: &'p Program,
    vars: &'p RayVars,
    args: &'p [f64],
    stack: Vec<Value>,
    /// The values of the file's variables (definitions without
    /// parameters) evaluated so far: the same for the whole evaluation, as
    /// Radiance keeps them for a ray.
    known: Vec<Option<f64>>,
    steps: u32,
    depth: u32,
    fault: Option<Fault>,
}

impl<'p> Eval<'p> {
    /// An evaluation of `program` for one ray, with the pattern's real arguments `args`.
    pub fn new(program: &'p Program, vars: &'p RayVars, args: &'p [f64]) -> Eval<'p> {
        Eval {
            program,
            vars,
            args,
            stack: STACKS.with(|s| s.borrow_mut().pop()).unwrap_or_default(),
            known: Vec::new(),
            steps: 0,
            depth: 0,
            fault: None,
        }
    }

    /// The value of root node `root`, or why it has none.
    pub fn value(&mut self, root: u32) -> Result<f64, Fault> {
        let v = self.node(root, 0, 0);
        match self.fault {
            Some(f) => Err(f),
            None => Ok(v),
        }
    }

    /// Calls `f` on numbers (a data pattern's function).
    pub fn call_with(&mut self, f: Callee, args: &[f64]) -> Result<f64, Fault> {
        let values: Vec<Value> = args.iter().map(|&v| Value::Num(v)).collect();
        let v = self.call(f, &values);
        match self.fault {
            Some(f) => Err(f),
            None => Ok(v),
        }
    }

    fn fail(&mut self, f: Fault) -> f64 {
        if self.fault.is_none() {
            self.fault = Some(f);
        }
        0.0
    }

    fn checked(&mut self, v: f64) -> f64 {
        if v.is_finite() {
            v
        } else {
            self.fail(Fault::Arithmetic)
        }
    }

    /// The value of node `id` in the frame of `count` values at `base`.
    fn node(&mut self, id: u32, base: usize, count: usize) -> f64 {
        if self.fault.is_some() {
            return 0.0;
        }
        self.steps += 1;
        if self.steps > MAX_STEPS {
            return self.fail(Fault::Budget);
        }
        let Some(node) = self.program.nodes.get(id as usize) else {
            return self.fail(Fault::Arithmetic);
        };
        match node {
            Node::Num(v) => *v,
            Node::Var(v) => self.vars.get(*v),
            Node::Param(i) => match (*i as usize) < count {
                true => match self.stack[base + *i as usize] {
                    Value::Num(v) => v,
                    Value::Func(_) => self.fail(Fault::Arithmetic),
                },
                false => self.fail(Fault::Arithmetic),
            },
            Node::Neg(a) => -self.node(*a, base, count),
            Node::Bin(op, a, b) => {
                let (x, y) = (self.node(*a, base, count), self.node(*b, base, count));
                match op {
                    0 => x + y,
                    1 => x - y,
                    2 => x * y,
                    3 if y == 0.0 => self.fail(Fault::Arithmetic),
                    3 => x / y,
                    _ => {
                        let v = x.powf(y);
                        self.checked(v)
                    }
                }
            }
            Node::Func(_) => self.fail(Fault::Arithmetic),
            Node::Call(Callee::Native(Builtin::If), args) => {
                let Some(&c) = args.first() else {
                    return self.fail(Fault::Arithmetic);
                };
                let pick = if self.node(c, base, count) > 0.0 { 1 } else { 2 };
                match args.get(pick) {
                    Some(&e) => self.node(e, base, count),
                    None => self.fail(Fault::Arithmetic),
                }
            }
            Node::Call(Callee::Native(Builtin::Select), args) => {
                let Some(&n) = args.first() else {
                    return self.fail(Fault::Arithmetic);
                };
                let n = self.node(n, base, count);
                if n < -0.5 {
                    return self.fail(Fault::Arithmetic);
                }
                let k = (n + 0.5) as usize;
                if k == 0 {
                    return (args.len() - 1) as f64;
                }
                match args.get(k) {
                    Some(&e) => self.node(e, base, count),
                    None => self.fail(Fault::Arithmetic),
                }
            }
            Node::Call(Callee::User(f), args) if args.is_empty() => {
                let f = *f as usize;
                if let Some(Some(v)) = self.known.get(f) {
                    return *v;
                }
                let v = self.call_on(Callee::User(f as u32), &[], base, count);
                if self.fault.is_none() {
                    if self.known.len() <= f {
                        self.known.resize(self.program.functions.len().max(f + 1), None);
                    }
                    self.known[f] = Some(v);
                }
                v
            }
            Node::Call(f, args) => self.call_on(*f, args, base, count),
            Node::CallParam(i, args) => {
                let f = match (*i as usize) < count {
                    true => self.stack[base + *i as usize],
                    false => return self.fail(Fault::Arithmetic),
                };
                let Value::Func(f) = f else {
                    return self.fail(Fault::Arithmetic);
                };
                self.call_on(f, args, base, count)
            }
        }
    }

    /// Calls `f` on the values of the argument nodes `args`, evaluated in
    /// the frame of `count` values at `base`.
    fn call_on(&mut self, f: Callee, args: &[u32], base: usize, count: usize) -> f64 {
        let top = self.stack.len();
        for &a in args {
            let v = self.argument(a, base, count);
            self.stack.push(v);
        }
        let v = self.invoke(f, top);
        self.stack.truncate(top);
        v
    }

    /// An argument's value: a function where the caller names one.
    fn argument(&mut self, a: u32, base: usize, count: usize) -> Value {
        match self.program.nodes.get(a as usize) {
            Some(Node::Func(f)) => Value::Func(*f),
            Some(Node::Param(i)) if (*i as usize) < count => self.stack[base + *i as usize],
            _ => Value::Num(self.node(a, base, count)),
        }
    }

    /// Calls `f` on the values from `top` to the end of the stack.
    fn invoke(&mut self, f: Callee, top: usize) -> f64 {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            self.depth -= 1;
            return self.fail(Fault::Budget);
        }
        let count = self.stack.len() - top;
        let v = match f {
            Callee::User(i) => match self.program.functions.get(i as usize) {
                Some(func) => {
                    let body = func.body;
                    self.node(body, top, count)
                }
                None => self.fail(Fault::Arithmetic),
            },
            Callee::Native(b) => {
                // Natives take few arguments: copied off the stack without
                // allocating, as this runs at every hit.
                let mut few = [Value::Num(0.0); 8];
                if count <= few.len() {
                    few[..count].copy_from_slice(&self.stack[top..]);
                    self.native(b, &few[..count])
                } else {
                    let args: Vec<Value> = self.stack[top..].to_vec();
                    self.native(b, &args)
                }
            }
        };
        self.depth -= 1;
        v
    }

    /// Calls `f` on `args`.
    fn call(&mut self, f: Callee, args: &[Value]) -> f64 {
        let top = self.stack.len();
        self.stack.extend_from_slice(args);
        let v = self.invoke(f, top);
        self.stack.truncate(top);
        v
    }

    /// The value of native `b` on `args`: one match arm per native, each a
    /// line or a few. Long because of that alone: a table of natives.
    fn native(&mut self, b: Builtin, args: &[Value]) -> f64 {
        use Builtin::*;
        let mut nums = [0.0f64; 4];
        let mut missing = false;
        for (k, n) in nums.iter_mut().enumerate() {
            match args.get(k) {
                Some(Value::Num(v)) => *n = *v,
                Some(Value::Func(_)) => {}
                None => missing = true,
            }
        }
        let need = |n: usize| args.len() >= n;
        let [a, b2, c, d] = nums;
        let v = self.vars;
        let deg = std::f64::consts::PI / 180.0;
        let out = match b {
            Pi => std::f64::consts::PI,
            Degree => deg,
            Ftiny => 1e-7,
            U | V => {
                let cc = v.get(Var::Nx).powi(2) + v.get(Var::Ny).powi(2);
                let (px, py, pz) = (v.get(Var::Px), v.get(Var::Py), v.get(Var::Pz));
                let (nx, ny, nz) = (v.get(Var::Nx), v.get(Var::Ny), v.get(Var::Nz));
                match (b, cc > 1e-7) {
                    (U, true) => (py * nx - px * ny) / cc,
                    (_, true) => pz - nz * (px * nx + py * ny) / cc,
                    (U, false) => px,
                    (_, false) => py,
                }
            }
            SrcTheta => v.get(Var::Dz).clamp(-1.0, 1.0).acos() / deg,
            SrcPhi(sym) => source_phi(v, f64::from(sym)),
            SrcBVert => safe_atan2(-v.get(Var::Dx), v.get(Var::Dz)) / deg,
            SrcBHoriz => safe_atan2(v.get(Var::Dy), v.get(Var::Dz)) / deg,
            SrcBVert2 => (safe_atan2(-v.get(Var::Dx), v.get(Var::Dz)) / deg).abs(),
            SrcBHoriz2 => (safe_atan2(v.get(Var::Dy), v.get(Var::Dz)) / deg).abs(),
            TiltAng | TiltAng2 => {
                let t = v.get(Var::Kz).clamp(-1.0, 1.0).acos() / deg;
                if b == TiltAng2 {
                    tri(t, 90.0)
                } else {
                    t
                }
            }
            TiltXang | TiltXang2 => {
                let (jy, jz) = (v.get(Var::Jy), v.get(Var::Jz));
                let t = if jy * jy <= 1e-7 {
                    0.0
                } else {
                    (jy / (jy * jy + jz * jz).sqrt()).clamp(-1.0, 1.0).asin() / deg
                };
                if b == TiltXang2 {
                    tri(t, 90.0)
                } else {
                    t
                }
            }
            _ if missing && !matches!(b, Min | Max | Arg) && arity(b) > args.len() => {
                return self.fail(Fault::Arithmetic);
            }
            Min | Max if args.is_empty() => return self.fail(Fault::Arithmetic),
            Min => args.iter().map(num).fold(f64::INFINITY, f64::min),
            Max => args.iter().map(num).fold(f64::NEG_INFINITY, f64::max),
            If => {
                if a > 0.0 {
                    b2
                } else {
                    c
                }
            }
            Select => {
                let k = (a + 0.5) as usize;
                if a < -0.5 || k >= args.len() {
                    return self.fail(Fault::Arithmetic);
                }
                if k == 0 {
                    (args.len() - 1) as f64
                } else {
                    num(&args[k])
                }
            }
            Arg => {
                let k = if args.is_empty() { 0 } else { (a + 0.5) as i64 };
                if k < 1 {
                    self.args.len() as f64
                } else {
                    match self.args.get(k as usize - 1) {
                        Some(&x) => x,
                        None => return self.fail(Fault::Arithmetic),
                    }
                }
            }
            Rand => builtin::rand(a),
            Floor => a.floor(),
            Ceil => a.ceil(),
            Sqrt => a.sqrt(),
            Sin => a.sin(),
            Cos => a.cos(),
            Tan => a.tan(),
            Asin => a.asin(),
            Acos => a.acos(),
            Atan => a.atan(),
            Atan2 => a.atan2(b2),
            Exp => a.exp(),
            Log => a.ln(),
            Log10 => a.log10(),
            Erf => builtin::erf(a),
            Erfc => 1.0 - builtin::erf(a),
            Noise3 => builtin::noise3(a, b2, c),
            Noise3x => builtin::noise3_slope(0, a, b2, c),
            Noise3y => builtin::noise3_slope(1, a, b2, c),
            Noise3z => builtin::noise3_slope(2, a, b2, c),
            Noise3d => {
                let k = (a + 0.5) as usize;
                if !(1..=3).contains(&k) {
                    return self.fail(Fault::Arithmetic);
                }
                builtin::noise3_slope(k - 1, b2, c, d)
            }
            Fnoise3 => builtin::fnoise3(a, b2, c),
            SourceCorr => self.corr(a, (b2 + 0.5) as u8),
            Corr(k) => self.corr(a, k),
            SourceTheta => v.get(Var::Dz).clamp(-1.0, 1.0).acos() / deg,
            SourcePhi => source_phi(v, a),
            Bound => {
                if a > b2 {
                    a
                } else if b2 > c {
                    c
                } else {
                    b2
                }
            }
            SafeAcos => a.clamp(-1.0, 1.0).acos(),
            SafeAsin => a.clamp(-1.0, 1.0).asin(),
            SafeAtan2 => safe_atan2(a, b2),
            SafeExp => {
                if a < -100.0 {
                    0.0
                } else {
                    a.exp()
                }
            }
            SafeSqrt => {
                if a <= 0.0 {
                    0.0
                } else {
                    a.sqrt()
                }
            }
            And => {
                if a > 0.0 {
                    b2
                } else {
                    a
                }
            }
            Or => {
                if a > 0.0 {
                    a
                } else {
                    b2
                }
            }
            Not => {
                if a > 0.0 {
                    -1.0
                } else {
                    1.0
                }
            }
            Xor => {
                if a > 0.0 {
                    if b2 > 0.0 {
                        -1.0
                    } else {
                        1.0
                    }
                } else {
                    b2
                }
            }
            Abs => a.abs(),
            Sgn => {
                if a > 0.0 {
                    1.0
                } else if a < 0.0 {
                    -1.0
                } else {
                    0.0
                }
            }
            Sq => a * a,
            Inside => {
                let (lo, hi) = (b2 - a, c - b2);
                if lo > 0.0 {
                    hi
                } else {
                    lo
                }
            }
            Frac => a - a.floor(),
            Mod => {
                if b2 == 0.0 {
                    return self.fail(Fault::Arithmetic);
                }
                a - (a / b2).floor() * b2
            }
            Tri => tri(a, b2),
            Linterp => (1.0 - a) * b2 + a * c,
            Noop => a,
            Clip => a.clamp(0.0, 1.0),
            Noneg | Red => a.max(0.0),
            Green => b2.max(0.0),
            Blue => c.max(0.0),
            Grey => (0.265_074_126 * a + 0.670_114_631 * b2 + 0.064_811_243 * c).max(0.0),
            ClipR => a.clamp(0.0, 1.0),
            ClipG => b2.clamp(0.0, 1.0),
            ClipB => c.clamp(0.0, 1.0),
            ClipGrey => (0.265_074_126 * a + 0.670_114_631 * b2 + 0.064_811_243 * c).clamp(0.0, 1.0),
            Fade => {
                if c < 16.0 {
                    b2 + (a - b2) / (1.0 + c * c)
                } else {
                    b2
                }
            }
            Hermite => {
                if !need(5) {
                    return self.fail(Fault::Arithmetic);
                }
                let t = num(&args[4]);
                let (t2, t3) = (t * t, t * t * t);
                a * (2.0 * t3 - 3.0 * t2 + 1.0) + b2 * (-2.0 * t3 + 3.0 * t2) + c * (t3 - 2.0 * t2 + t) + d * (t3 - t2)
            }
            Bezier => {
                if !need(5) {
                    return self.fail(Fault::Arithmetic);
                }
                let t = num(&args[4]);
                let s = 1.0 - t;
                a * s * s * s + 3.0 * b2 * t * s * s + 3.0 * c * t * t * s + d * t * t * t
            }
            Bspline => {
                if !need(5) {
                    return self.fail(Fault::Arithmetic);
                }
                let t = num(&args[4]);
                let (t2, t3) = (t * t, t * t * t);
                (a * (-t3 + 3.0 * t2 - 3.0 * t + 1.0)
                    + b2 * (3.0 * t3 - 6.0 * t2 + 4.0)
                    + c * (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0)
                    + d * t3)
                    / 6.0
            }
            Turbulence => {
                // Octaves s, 2s, 4s, ... while at most 1.01.
                let (mut s, mut sum) = (d, 0.0);
                if s <= 0.0 {
                    return self.fail(Fault::Arithmetic);
                }
                while s <= 1.01 {
                    sum += builtin::noise3(a / s, b2 / s, c / s).abs() * s;
                    s *= 2.0;
                }
                sum
            }
            Unif2Norm => builtin::unif2norm(a),
            Nrand => builtin::unif2norm(builtin::rand(a)),
            DComp | NComp | PComp => {
                let k = (a + 0.5) as usize;
                if !(1..=3).contains(&k) {
                    return self.fail(Fault::Arithmetic);
                }
                let base = match b {
                    DComp => [Var::Dx, Var::Dy, Var::Dz],
                    NComp => [Var::Nx, Var::Ny, Var::Nz],
                    _ => [Var::Px, Var::Py, Var::Pz],
                };
                v.get(base[k - 1])
            }
            Dot | Cross => {
                let (fa, fb, first) = match b {
                    Dot => (args.first(), args.get(1), 0),
                    _ => (args.get(1), args.get(2), 1),
                };
                let (Some(Value::Func(f1)), Some(Value::Func(f2))) = (fa.copied(), fb.copied()) else {
                    return self.fail(Fault::Arithmetic);
                };
                let mut comp = |f: Callee, i: f64| self.call(f, &[Value::Num(i)]);
                let x = [comp(f1, 1.0), comp(f1, 2.0), comp(f1, 3.0)];
                let y = [comp(f2, 1.0), comp(f2, 2.0), comp(f2, 3.0)];
                if first == 0 {
                    x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
                } else {
                    let cross = [
                        x[1] * y[2] - x[2] * y[1],
                        x[2] * y[0] - x[0] * y[2],
                        x[0] * y[1] - x[1] * y[0],
                    ];
                    let k = (a + 0.5) as usize;
                    match k {
                        1..=3 => cross[k - 1],
                        _ => return self.fail(Fault::Arithmetic),
                    }
                }
            }
        };
        self.checked(out)
    }

    /// `source_corr(v, k)`: a light's intensity `v` (times the first real
    /// argument where there is one) divided by the area the source shows
    /// toward the ray: 0 none, 1 flat, 2 box, 3 box seen from close by,
    /// 4 cylinder along z.
    fn corr(&mut self, value: f64, kind: u8) -> f64 {
        let v = self.vars;
        let a = |k: usize| self.args.get(k).copied().unwrap_or(0.0);
        let scaled = if self.args.is_empty() { value } else { value * a(0) };
        if scaled <= 0.0 {
            return 0.0;
        }
        let (dx, dy, dz) = (v.get(Var::Dx), v.get(Var::Dy), v.get(Var::Dz));
        let area = match kind {
            0 => 1.0,
            1 => v.get(Var::Rdot),
            2 => dx.abs() * a(2) * a(3) + dy.abs() * a(1) * a(3) + dz.abs() * a(1) * a(2),
            3 => {
                let ts = v.get(Var::Ts);
                let p = [v.get(Var::Px), v.get(Var::Py), v.get(Var::Pz)];
                let d = [dx, dy, dz];
                let size = [a(1), a(2), a(3)];
                let mut den = 0.0;
                for k in 0..3 {
                    let out = ((p[k] - d[k] * ts).abs() - size[k] / 2.0).max(0.0);
                    den += out * size[(k + 1) % 3] * size[(k + 2) % 3];
                }
                if den <= 0.0 {
                    return self.fail(Fault::Arithmetic);
                }
                return self.checked(scaled * ts / den);
            }
            4 => {
                let z = dz.abs().min(1.0 - 1e-9);
                a(1) * a(2) * (1.0 - z * z).sqrt() + std::f64::consts::FRAC_PI_4 * a(1) * a(1) * z
            }
            _ => return self.fail(Fault::Arithmetic),
        };
        if area <= 0.0 {
            return self.fail(Fault::Arithmetic);
        }
        scaled / area
    }
}

/// A number argument (0 for a function passed by name).
fn num(v: &Value) -> f64 {
    match v {
        Value::Num(x) => *x,
        Value::Func(_) => 0.0,
    }
}

/// How many arguments a native needs.
fn arity(b: Builtin) -> usize {
    use Builtin::*;
    match b {
        If | Bound | Linterp | Noise3 | Noise3x | Noise3y | Noise3z | Fnoise3 | Inside | Fade | Red | Green | Blue
        | Grey | ClipR | ClipG | ClipB | ClipGrey | Cross => 3,
        Atan2 | SafeAtan2 | And | Or | Xor | Mod | Tri | SourceCorr | Dot => 2,
        Noise3d | Turbulence => 4,
        Hermite | Bezier | Bspline => 5,
        _ => 1,
    }
}

/// `atan2` that is 0 where both are 0.
fn safe_atan2(y: f64, x: f64) -> f64 {
    if x * x + y * y > 0.0 {
        y.atan2(x)
    } else {
        0.0
    }
}

/// A triangle wave folding `n` into [0, `d`].
fn tri(n: f64, d: f64) -> f64 {
    if d == 0.0 {
        return 0.0;
    }
    let m = n - d;
    let two = 2.0 * d;
    (d - (m - (m / two).floor() * two)).abs()
}

/// The emission azimuth of a light-source ray, degrees, folded for a
/// source symmetric every `sym` degrees (360, 180 or 90).
fn source_phi(v: &RayVars, sym: f64) -> f64 {
    let mut phi = safe_atan2(-v.get(Var::Dy), -v.get(Var::Dx)).to_degrees();
    if phi < 0.0 {
        phi += 360.0;
    }
    if sym <= 90.5 {
        if phi >= 180.0 {
            phi -= 180.0;
        }
        if phi >= 90.0 {
            phi = 180.0 - phi;
        }
    } else if sym <= 180.5 && phi >= 180.0 {
        phi = 360.0 - phi;
    }
    phi
}
