//! The branches a shader takes on uniform-buffer values alone: what lavapipe (Mesa 22.3, the
//! CI's and this machine's Vulkan) inlines. At each draw after a pipeline is bound with new
//! descriptor sets, lavapipe clones such a shader's NIR, replaces the uniform loads that decide
//! an `if` or a loop's exit with the values in the buffer, optimises it and compiles it again
//! (`update_inline_shader_state`, lvp_execute.c; `lvp_find_inlinable_uniforms`,
//! lvp_inline_uniforms.c), unless the first try shrank the shader by less than half. Even with
//! Mesa's shader cache answering the compile, that re-optimisation is milliseconds per pipeline
//! per frame, whatever the model covers on screen (docs/PERFORMANCE.md, twenty-sixth session).
//!
//! [`uniform_branches`] finds them in a naga module: the conditions of `if`s, loop exits and
//! `switch`es whose value depends on a `var<uniform>` load and on nothing that varies per
//! invocation (entry-point inputs, texture reads, storage buffers, derivatives), followed
//! through locals, function arguments and results as NIR's function inlining would see them.
//! Literals and pipeline-override constants are fixed when the pipeline is made and do not
//! count; a branch they decide is not looked into on the side not taken. `&&` and `||` reach
//! naga as an `if` storing into a local, which this does not decide: the code behind such a
//! condition on constants is checked as if it could run (a false alarm at worst).

use naga::{AddressSpace, Block, Expression, Function, Handle, Module, Statement};

/// What an expression's value depends on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Depends {
    /// A value that differs between invocations (or that lavapipe cannot inline).
    varies: bool,
    /// A load from a uniform buffer.
    uniform: bool,
}

impl Depends {
    const VARIES: Depends = Depends { varies: true, uniform: false };
    const UNIFORM: Depends = Depends { varies: false, uniform: true };

    fn join(self, other: Depends) -> Depends {
        Depends { varies: self.varies || other.varies, uniform: self.uniform || other.uniform }
    }

    /// A branch on this value is one lavapipe inlines.
    fn inlined(self) -> bool {
        self.uniform && !self.varies
    }
}

/// Per function: what its arguments (joined over every call) and its result depend on.
#[derive(Clone, Debug, Default, PartialEq)]
struct Summary {
    arguments: Vec<Depends>,
    result: Depends,
}

/// Where a uniform-only branch is: the function's name and the kind of statement.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UniformBranch {
    pub function: String,
    pub statement: &'static str,
}

impl std::fmt::Display for UniformBranch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} in fn {}", self.statement, self.function)
    }
}

/// The branches of `module`'s entry point `entry` (and of every function it calls) whose
/// conditions lavapipe inlines (module docs), in a pipeline made with the override `constants`
/// (name, value; the others at their defaults): a branch whose condition those constants decide
/// is not a branch, and only the side taken is looked into. Empty when `entry` is not in the
/// module.
pub fn uniform_branches(module: &Module, entry: &str, constants: &[(&str, f64)]) -> Vec<UniformBranch> {
    let Some(ep) = module.entry_points.iter().find(|e| e.name == entry) else { return Vec::new() };
    let fixed = Fixed { module, constants };
    let mut summaries: Vec<Summary> = module
        .functions
        .iter()
        .map(|(_, f)| Summary { arguments: vec![Depends::default(); f.arguments.len()], ..Default::default() })
        .collect();
    let entry_args = vec![Depends::VARIES; ep.function.arguments.len()];
    let ep_name = format!("{} (entry point)", ep.name);
    // Arguments and results flow between functions: repeat until nothing changes.
    let mut found = Vec::new();
    // What each function (and, last, the entry point) calls on the sides of branches taken.
    let mut callees = vec![Vec::new(); summaries.len() + 1];
    for _ in 0..64 {
        let before = summaries.clone();
        found.clear();
        callees.iter_mut().for_each(Vec::clear);
        let mut calls = vec![Vec::new(); summaries.len()];
        for (h, f) in module.functions.iter() {
            let name = f.name.clone().unwrap_or_default();
            let args = summaries[h.index()].arguments.clone();
            let mut out = Out { calls: &mut calls, callees: &mut callees[h.index()], found: &mut found };
            summaries[h.index()].result = analyse(&fixed, (f, &name), &args, &summaries, &mut out);
        }
        let mut out = Out { calls: &mut calls, callees: &mut callees[summaries.len()], found: &mut found };
        analyse(&fixed, (&ep.function, &ep_name), &entry_args, &summaries, &mut out);
        for (callee, seen) in calls.into_iter().enumerate() {
            for args in seen {
                for (slot, d) in summaries[callee].arguments.iter_mut().zip(args) {
                    *slot = slot.join(d);
                }
            }
        }
        if summaries == before {
            break;
        }
    }
    // Only functions reachable from the entry point matter.
    let mut stack = callees[summaries.len()].clone();
    let mut reachable = Vec::new();
    while let Some(h) = stack.pop() {
        let name = module.functions[h].name.clone().unwrap_or_default();
        if !reachable.contains(&name) {
            reachable.push(name);
            stack.extend_from_slice(&callees[h.index()]);
        }
    }
    found.into_iter().filter(|b| b.function == ep_name || reachable.contains(&b.function)).collect()
}

/// Where [`analyse`] records what it finds: each callee's arguments at each call (by callee),
/// the functions the analysed one calls, and its uniform-only branches.
struct Out<'b> {
    calls: &'b mut [Vec<Vec<Depends>>],
    callees: &'b mut Vec<Handle<Function>>,
    found: &'b mut Vec<UniformBranch>,
}

/// The module with its pipeline's override constants: what a condition is when they decide it.
struct Fixed<'a> {
    module: &'a Module,
    constants: &'a [(&'a str, f64)],
}

impl Fixed<'_> {
    /// The value of function `f`'s expression `e` when literals, constants and overrides
    /// decide it (booleans as 0/1), else None.
    fn value(&self, f: &Function, e: Handle<Expression>) -> Option<f64> {
        self.expr_value(&f.expressions[e], &|h| self.value(f, h))
    }

    /// The truth of function `f`'s condition `e` when the constants decide it.
    fn truth(&self, f: &Function, e: Handle<Expression>) -> Option<bool> {
        self.value(f, e).map(|v| v != 0.0)
    }

    fn global_value(&self, e: Handle<Expression>) -> Option<f64> {
        self.expr_value(&self.module.global_expressions[e], &|h| self.global_value(h))
    }

    fn expr_value(&self, e: &Expression, operand: &dyn Fn(Handle<Expression>) -> Option<f64>) -> Option<f64> {
        use naga::{BinaryOperator as B, Literal as L, UnaryOperator as U};
        let bool_value = |b: bool| if b { 1.0 } else { 0.0 };
        Some(match e {
            Expression::Literal(l) => match *l {
                L::Bool(b) => bool_value(b),
                L::U32(v) => f64::from(v),
                L::I32(v) => f64::from(v),
                L::F32(v) => f64::from(v),
                L::AbstractInt(v) => v as f64,
                L::AbstractFloat(v) => v,
                _ => return None,
            },
            Expression::Constant(c) => self.global_value(self.module.constants[*c].init)?,
            Expression::Override(o) => {
                let o = &self.module.overrides[*o];
                let name = o.name.as_deref().unwrap_or_default();
                match self.constants.iter().find(|(n, _)| *n == name) {
                    Some(&(_, v)) => v,
                    None => self.global_value(o.init?)?,
                }
            }
            Expression::Unary { op: U::LogicalNot, expr } => bool_value(operand(*expr)? == 0.0),
            Expression::Unary { op: U::Negate, expr } => -operand(*expr)?,
            Expression::Binary { op, left, right } => {
                let (a, b) = (operand(*left)?, operand(*right)?);
                match op {
                    B::Equal => bool_value(a == b),
                    B::NotEqual => bool_value(a != b),
                    B::Less => bool_value(a < b),
                    B::LessEqual => bool_value(a <= b),
                    B::Greater => bool_value(a > b),
                    B::GreaterEqual => bool_value(a >= b),
                    B::LogicalAnd => bool_value(a != 0.0 && b != 0.0),
                    B::LogicalOr => bool_value(a != 0.0 || b != 0.0),
                    // Booleans (0, 1) and unsigned integers bit by bit.
                    B::And => ((a as u64) & (b as u64)) as f64,
                    B::InclusiveOr => ((a as u64) | (b as u64)) as f64,
                    B::ExclusiveOr => ((a as u64) ^ (b as u64)) as f64,
                    B::Add => a + b,
                    B::Subtract => a - b,
                    B::Multiply => a * b,
                    _ => return None,
                }
            }
            _ => return None,
        })
    }
}

/// One function `f` named `name` with arguments depending on `args`: records its calls and
/// uniform-only branches in `out`; returns what its result depends on.
fn analyse(fixed: &Fixed, (f, name): (&Function, &str), args: &[Depends], summaries: &[Summary], out: &mut Out) -> Depends {
    // NIR keeps a local stored once as that value, and makes one stored in several places a phi,
    // which lavapipe does not look through except in a loop's exit (its induction variables).
    let mut count = vec![0usize; f.local_variables.len()];
    for (h, v) in f.local_variables.iter() {
        count[h.index()] += usize::from(v.init.is_some());
    }
    // A store in a loop is a phi at the loop's head.
    local_stores(f, &f.body, false, &mut |l, _, in_loop| count[l.index()] += if in_loop { 2 } else { 1 });
    let mut locals = vec![Depends::default(); f.local_variables.len()];
    let mut exprs = vec![Depends::default(); f.expressions.len()];
    // Locals take every value stored into them, which may depend on their own loads: repeat.
    for _ in 0..64 {
        for (h, e) in f.expressions.iter() {
            exprs[h.index()] = expression(fixed.module, e, &exprs, &locals, args, summaries);
        }
        let mut next = locals.clone();
        for (h, v) in f.local_variables.iter() {
            if let Some(init) = v.init {
                next[h.index()] = next[h.index()].join(exprs[init.index()]);
            }
        }
        local_stores(f, &f.body, false, &mut |l, value, _| next[l.index()] = next[l.index()].join(exprs[value.index()]));
        if next == locals {
            break;
        }
        locals = next;
    }
    // The same values with the locals stored in several places as phis.
    let phis: Vec<Depends> = locals.iter().zip(&count).map(|(&d, &n)| if n > 1 { d.join(Depends::VARIES) } else { d }).collect();
    let mut direct = vec![Depends::default(); f.expressions.len()];
    for (h, e) in f.expressions.iter() {
        direct[h.index()] = expression(fixed.module, e, &direct, &phis, args, summaries);
    }
    let mut walk = Walk { fixed, f, exprs: &direct, loop_exprs: &exprs, name, result: Depends::default(), out, in_loop: false };
    walk.block(&f.body);
    walk.result
}

/// What expression `e` depends on, its operands' dependencies already in `exprs`.
fn expression(module: &Module, e: &Expression, exprs: &[Depends], locals: &[Depends], args: &[Depends], s: &[Summary]) -> Depends {
    let d = |h: &Handle<Expression>| exprs[h.index()];
    let all = |hs: &[Handle<Expression>]| hs.iter().fold(Depends::default(), |a, h| a.join(d(h)));
    match e {
        Expression::Literal(_) | Expression::Constant(_) | Expression::Override(_) | Expression::ZeroValue(_) => Depends::default(),
        Expression::Compose { components, .. } => all(components),
        Expression::Access { base, index } => d(base).join(d(index)),
        Expression::AccessIndex { base, .. } => d(base),
        Expression::Splat { value, .. } => d(value),
        Expression::Swizzle { vector, .. } => d(vector),
        Expression::FunctionArgument(i) => args.get(*i as usize).copied().unwrap_or(Depends::VARIES),
        // A pointer: what a load through it gives.
        Expression::GlobalVariable(g) => match module.global_variables[*g].space {
            AddressSpace::Uniform => Depends::UNIFORM,
            _ => Depends::VARIES,
        },
        Expression::LocalVariable(l) => locals[l.index()],
        Expression::Load { pointer } => d(pointer),
        Expression::Unary { expr, .. } => d(expr),
        Expression::Binary { left, right, .. } => d(left).join(d(right)),
        Expression::Select { condition, accept, reject } => d(condition).join(d(accept)).join(d(reject)),
        Expression::Relational { argument, .. } => d(argument),
        Expression::Math { arg, arg1, arg2, arg3, .. } => {
            [Some(*arg), *arg1, *arg2, *arg3].iter().flatten().fold(Depends::default(), |a, h| a.join(d(h)))
        }
        Expression::As { expr, .. } => d(expr),
        Expression::CallResult(f) => s[f.index()].result,
        // Texture reads, derivatives, storage, atomics, queries: they vary.
        _ => Depends::VARIES,
    }
}

/// Call `visit(local, value, in_loop)` for every value `block` stores into a local variable
/// (through any access); `in_loop`: the store is inside a loop.
fn local_stores(f: &Function, block: &Block, in_loop: bool, visit: &mut dyn FnMut(Handle<naga::LocalVariable>, Handle<Expression>, bool)) {
    for s in block.iter() {
        match s {
            Statement::Store { pointer, value } => {
                if let Some(l) = root_local(f, *pointer) {
                    visit(l, *value, in_loop);
                }
            }
            Statement::Block(b) => local_stores(f, b, in_loop, visit),
            Statement::If { accept, reject, .. } => {
                local_stores(f, accept, in_loop, visit);
                local_stores(f, reject, in_loop, visit);
            }
            Statement::Switch { cases, .. } => cases.iter().for_each(|c| local_stores(f, &c.body, in_loop, visit)),
            Statement::Loop { body, continuing, .. } => {
                local_stores(f, body, true, visit);
                local_stores(f, continuing, true, visit);
            }
            _ => {}
        }
    }
}

/// The local variable a pointer expression points into, if it does.
fn root_local(f: &Function, mut p: Handle<Expression>) -> Option<Handle<naga::LocalVariable>> {
    loop {
        match f.expressions[p] {
            Expression::LocalVariable(l) => return Some(l),
            Expression::Access { base, .. } | Expression::AccessIndex { base, .. } => p = base,
            _ => return None,
        }
    }
}

/// A walk through a function's statements on the sides of branches taken, recording its
/// uniform-only branches, its calls' arguments and what its result depends on.
struct Walk<'a, 'b> {
    fixed: &'a Fixed<'a>,
    f: &'a Function,
    /// With the locals stored in several places as phis.
    exprs: &'a [Depends],
    /// With every local as the values stored into it (a loop's exit).
    loop_exprs: &'a [Depends],
    in_loop: bool,
    name: &'a str,
    result: Depends,
    out: &'a mut Out<'b>,
}

impl Walk<'_, '_> {
    fn check(&mut self, h: Handle<Expression>, statement: &'static str, exit: bool) {
        let d = if exit { self.loop_exprs[h.index()] } else { self.exprs[h.index()] };
        if d.inlined() {
            self.out.found.push(UniformBranch { function: self.name.to_string(), statement });
        }
    }

    fn block(&mut self, block: &Block) {
        for s in block.iter() {
            match s {
                Statement::If { condition, accept, reject } => match self.fixed.truth(self.f, *condition) {
                    Some(true) => self.block(accept),
                    Some(false) => self.block(reject),
                    None => {
                        // A loop's exit: `if (c) { break; }` (naga's `for` and `while`).
                        let exit = self.in_loop && [accept, reject].iter().any(|b| matches!(b.iter().next(), Some(Statement::Break)));
                        self.check(*condition, if exit { "loop exit" } else { "if" }, exit);
                        self.block(accept);
                        self.block(reject);
                    }
                },
                Statement::Switch { selector, cases } => {
                    self.check(*selector, "switch", false);
                    for c in cases {
                        self.block(&c.body);
                    }
                }
                Statement::Loop { body, continuing, break_if } => {
                    if let Some(b) = break_if {
                        self.check(*b, "loop exit", true);
                    }
                    let outer = std::mem::replace(&mut self.in_loop, true);
                    self.block(body);
                    self.block(continuing);
                    self.in_loop = outer;
                }
                Statement::Block(b) => self.block(b),
                Statement::Return { value: Some(v) } => self.result = self.result.join(self.exprs[v.index()]),
                Statement::Call { function, arguments, .. } => {
                    self.out.calls[function.index()].push(arguments.iter().map(|a| self.exprs[a.index()]).collect());
                    self.out.callees.push(*function);
                }
                _ => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn branches(src: &str, entry: &str) -> Vec<String> {
        let module = crate::gpu::wgsl::validate(src).unwrap();
        uniform_branches(&module, entry, &[]).iter().map(|b| b.to_string()).collect()
    }

    const HEAD: &str = "struct U { a: f32, n: u32 }; @group(0) @binding(0) var<uniform> u: U;
        @group(0) @binding(1) var<storage, read> s: U;
        override K: f32 = 1.0;\n";

    #[test]
    fn a_branch_on_a_uniform_is_found_one_on_a_varying_value_is_not() {
        let src = format!(
            "{HEAD}@fragment fn fs(@location(0) x: f32) -> @location(0) vec4<f32> {{
                var c = 0.0;
                if (u.a > 0.5) {{ c = 1.0; }}
                if (u.a > x) {{ c = 2.0; }}
                if (K > 0.5) {{ c = 3.0; }}
                if (s.a > 0.5) {{ c = 4.0; }}
                return vec4<f32>(c);
            }}"
        );
        assert_eq!(branches(&src, "fs"), ["if in fn fs (entry point)"]);
    }

    #[test]
    fn override_constants_decide_their_branches_and_only_the_side_taken_counts() {
        let src = format!(
            "{HEAD}override ON: bool = true;
            fn helper(x: f32) -> f32 {{ if (u.a > 0.5) {{ return x; }} return -x; }}
            @fragment fn fs(@location(0) x: f32) -> @location(0) vec4<f32> {{
                var c = x;
                if (ON) {{ c = helper(x); }}
                if ((K >= 2.0) & !ON) {{ if (u.n == 3u) {{ c = 0.0; }} }}
                if (K >= 2.0 && !ON) {{ c += 1.0; }}
                return vec4<f32>(c);
            }}"
        );
        let module = crate::gpu::wgsl::validate(&src).unwrap();
        let found = |constants: &[(&str, f64)]| -> Vec<String> {
            uniform_branches(&module, "fs", constants).iter().map(|b| b.to_string()).collect()
        };
        // Defaults (ON, K = 1): the helper is called, the second block is not taken.
        assert_eq!(found(&[]), ["if in fn helper"]);
        assert!(found(&[("ON", 0.0)]).is_empty());
        assert_eq!(found(&[("ON", 0.0), ("K", 2.0)]), ["if in fn fs (entry point)"]);
    }

    #[test]
    fn values_are_followed_through_locals_arguments_and_results() {
        let src = format!(
            "{HEAD}fn strength() -> f32 {{ return u.a * 2.0; }}
            fn lit(x: f32, k: f32) -> f32 {{ if (k > 0.0) {{ return x * k; }} return x; }}
            @fragment fn fs(@location(0) x: f32) -> @location(0) vec4<f32> {{
                var k = strength();
                return vec4<f32>(lit(x, k));
            }}"
        );
        assert_eq!(branches(&src, "fs"), ["if in fn lit"]);
        // The same helper called with a varying value at one place is not inlined.
        let src = format!(
            "{HEAD}fn lit(x: f32, k: f32) -> f32 {{ if (k > 0.0) {{ return x * k; }} return x; }}
            @fragment fn fs(@location(0) x: f32) -> @location(0) vec4<f32> {{
                return vec4<f32>(lit(x, u.a) + lit(x, x));
            }}"
        );
        assert!(branches(&src, "fs").is_empty());
    }

    #[test]
    fn a_value_chosen_in_branches_is_a_phi_and_not_inlined() {
        // `a && b` with a varying `a`: naga keeps the uniform `b` in a local stored on both sides
        // of a branch on `a`, which NIR turns into a phi.
        let src = format!(
            "{HEAD}@fragment fn fs(@location(0) x: f32, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {{
                var c = x;
                var k = 0.0;
                if (x > 0.0) {{ k = u.a; }} else {{ k = 2.0 * u.a; }}
                if (k > 1.0) {{ c = 1.0; }}
                if (!front && u.a > 0.5) {{ c = -c; }}
                let once = u.a * 3.0;
                if (once > 1.0) {{ c = 2.0; }}
                return vec4<f32>(c);
            }}"
        );
        assert_eq!(branches(&src, "fs"), ["if in fn fs (entry point)"]);
    }

    #[test]
    fn a_loop_bounded_by_a_uniform_is_found() {
        // lavapipe inlines a loop's bound when its exit compares the induction variable with it.
        let src = format!(
            "{HEAD}@fragment fn fs(@location(0) x: f32) -> @location(0) vec4<f32> {{
                var c = 0.0;
                for (var i = 0u; i < u.n; i++) {{ c += x; }}
                for (var i = 0u; i < 4u; i++) {{ c += x; }}
                return vec4<f32>(c);
            }}"
        );
        assert_eq!(branches(&src, "fs"), ["loop exit in fn fs (entry point)"]);
        // Another entry point of the module, or one that is not there, has none.
        assert!(branches(&src, "missing").is_empty());
    }
}
