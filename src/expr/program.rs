//! Expressions compiled to a flat instruction list over a shared DAG (common sub-expressions
//! merged), evaluated in f64 over many points at once: each instruction runs over a chunk of
//! points before the next starts, so the loop bodies vectorise and nothing walks a tree.
//! The WGSL emitter walks the same DAG, so CPU and GPU compute the same operations in the same
//! order.

use std::collections::HashMap;

use crate::expr::ast::{powi, Expr, Op1, Op2};
use crate::memory::Ticks;

/// Points per chunk: registers are arrays of this many lanes.
pub const LANES: usize = 64;

/// One node of the DAG.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Node {
    /// Variable x_i (0-based).
    Var(usize),
    /// A constant.
    Const(f64),
    /// One-argument operation on an earlier node.
    Un(Op1, u32),
    /// Two-argument operation on earlier nodes.
    Bin(Op2, u32, u32),
    /// Integer power of an earlier node.
    PowI(u32, i32),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum NodeKey {
    Var(usize),
    Const(u64),
    Un(Op1, u32),
    Bin(Op2, u32, u32),
    PowI(u32, i32),
}

/// A compiled list of expressions in d variables.
///
/// ```
/// use isomesh::expr::program::Program;
/// use isomesh::expr::{parse_expr, Scope};
///
/// let e = parse_expr("x^2 + y^2 - 1", &Scope::new(2))?;
/// let p = Program::compile(std::slice::from_ref(&e), 2);
/// let mut out = [0.0];
/// p.eval(&[0.6, 0.8], &mut out);
/// assert_eq!(out[0], e.eval(&[0.6, 0.8]));
/// # Ok::<(), isomesh::expr::ParseError>(())
/// ```
#[derive(Clone, Debug)]
pub struct Program {
    dim: usize,
    nodes: Vec<Node>,
    outputs: Vec<u32>,
    /// The operations, fused and with registers allocated, in evaluation order.
    instrs: Vec<Instr>,
    /// Constant registers and their values.
    consts: Vec<(u32, f64)>,
    /// Register holding each output.
    out_regs: Vec<u32>,
    n_regs: usize,
}

/// Scratch registers for [`Program::eval_batch`]; reuse one per thread.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    regs: Vec<[f64; LANES]>,
    /// One lane, for a single point.
    one: Vec<[f64; 1]>,
}

struct Builder {
    nodes: Vec<Node>,
    index: HashMap<NodeKey, u32>,
}

impl Builder {
    fn intern(&mut self, node: Node) -> u32 {
        let key = match node {
            Node::Var(i) => NodeKey::Var(i),
            // -0.0 and 0.0 stay distinct: their bits differ.
            Node::Const(v) => NodeKey::Const(v.to_bits()),
            Node::Un(op, a) => NodeKey::Un(op, a),
            Node::Bin(op, a, b) => NodeKey::Bin(op, a, b),
            Node::PowI(a, n) => NodeKey::PowI(a, n),
        };
        if let Some(&id) = self.index.get(&key) {
            return id;
        }
        let id = self.nodes.len() as u32;
        self.nodes.push(node);
        self.index.insert(key, id);
        id
    }

    fn add(&mut self, e: &Expr, ticks: &mut Ticks) -> Result<u32, u64> {
        ticks.tick()?;
        let node = match e {
            Expr::Num(v) => Node::Const(*v),
            Expr::Var(i) => Node::Var(*i),
            Expr::Un(op, a) => {
                let a = self.add(a, ticks)?;
                Node::Un(*op, a)
            }
            Expr::Bin(op, a, b) => {
                let a = self.add(a, ticks)?;
                let b = self.add(b, ticks)?;
                Node::Bin(*op, a, b)
            }
            Expr::PowI(a, n) => {
                let a = self.add(a, ticks)?;
                Node::PowI(a, *n)
            }
        };
        Ok(self.intern(node))
    }
}

impl Program {
    /// Compiles `exprs` (in variables x_1..x_dim) into one program with one output each.
    pub fn compile(exprs: &[Expr], dim: usize) -> Program {
        match Program::build(exprs, dim, &mut Ticks::unchecked()) {
            Ok(p) => p,
            Err(_) => unreachable!("unchecked steps never fail"),
        }
    }

    /// [`Program::compile`], stopping with the limit once the heap passes this thread's
    /// memory limit (see [`crate::memory::within`]).
    pub fn compile_within_limit(exprs: &[Expr], dim: usize) -> Result<Program, crate::Error> {
        Program::build(exprs, dim, &mut Ticks::checked()).map_err(|limit| {
            crate::Error::MemoryLimit {
                what: "compiling the equations".into(),
                limit,
                advice: "write smaller equations".into(),
            }
        })
    }

    fn build(exprs: &[Expr], dim: usize, ticks: &mut Ticks) -> Result<Program, u64> {
        let mut b = Builder {
            nodes: Vec::new(),
            index: HashMap::new(),
        };
        // Variables first, so that register i holds x_i.
        for i in 0..dim {
            b.intern(Node::Var(i));
        }
        let outputs = exprs
            .iter()
            .map(|e| b.add(e, ticks))
            .collect::<Result<Vec<u32>, u64>>()?;
        let nodes = b.nodes;
        let plan = fuse(&nodes, &outputs);

        // Register allocation over the fused instructions: variables and constants keep their
        // own registers; an instruction's result register is freed after its last reader
        // (outputs live to the end).
        let mut reg = vec![u32::MAX; nodes.len()];
        let mut n_regs = 0u32;
        for (i, n) in nodes.iter().enumerate() {
            if matches!(n, Node::Var(_) | Node::Const(_)) {
                reg[i] = n_regs;
                n_regs += 1;
            }
        }
        let mut last_read = vec![0usize; nodes.len()];
        for (t, p) in plan.iter().enumerate() {
            let (a, b) = p.core.inputs();
            last_read[a as usize] = t;
            last_read[b as usize] = t;
        }
        for &o in &outputs {
            last_read[o as usize] = usize::MAX;
        }
        let mut free: Vec<u32> = Vec::new();
        let mut instrs = Vec::with_capacity(plan.len());
        for (t, p) in plan.iter().enumerate() {
            // The destination is chosen before this instruction's inputs are freed, so it
            // never aliases an input (run() relies on this).
            let dst = free.pop().unwrap_or_else(|| {
                n_regs += 1;
                n_regs - 1
            });
            reg[p.node as usize] = dst;
            instrs.push(Instr {
                core: p.core.map(|a| reg[a as usize]),
                post: p.post,
                dst,
            });
            let (a, b) = p.core.inputs();
            for a in [Some(a), (b != a).then_some(b)].into_iter().flatten() {
                let a = a as usize;
                if last_read[a] == t && !matches!(nodes[a], Node::Var(_) | Node::Const(_)) {
                    free.push(reg[a]);
                }
            }
        }
        let consts = nodes
            .iter()
            .enumerate()
            .filter_map(|(i, n)| match n {
                Node::Const(v) => Some((reg[i], *v)),
                _ => None,
            })
            .collect();
        let out_regs = outputs.iter().map(|&o| reg[o as usize]).collect();
        Ok(Program {
            dim,
            nodes,
            outputs,
            instrs,
            consts,
            out_regs,
            n_regs: n_regs as usize,
        })
    }

    /// Number of variables.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.outputs.len()
    }

    /// The DAG, in evaluation order (arguments before uses).
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The node computing each output.
    pub fn output_nodes(&self) -> &[u32] {
        &self.outputs
    }

    /// Evaluates at one point.
    pub fn eval(&self, x: &[f64], out: &mut [f64]) {
        let mut scratch = Scratch::default();
        self.eval_batch(x, out, &mut scratch);
    }

    /// Evaluates at n points: `points` is n rows of `dim`, `out` n rows of `outputs()`.
    pub fn eval_batch(&self, points: &[f64], out: &mut [f64], scratch: &mut Scratch) {
        let (d, k) = (self.dim, self.outputs.len());
        let n = points.len().checked_div(d).unwrap_or(0);
        assert_eq!(
            out.len(),
            n * k,
            "output buffer must hold n * outputs values"
        );
        // One point (a Newton step, the gradient at a polygon's centre) runs on one lane: the
        // same operations on the same values, so the same result, without 63 idle lanes.
        if n == 1 {
            self.eval_lanes(points, out, &mut scratch.one);
        } else {
            self.eval_lanes(points, out, &mut scratch.regs);
        }
    }

    /// [`Program::eval_batch`] over `L` lanes at a time.
    fn eval_lanes<const L: usize>(
        &self,
        points: &[f64],
        out: &mut [f64],
        regs: &mut Vec<[f64; L]>,
    ) {
        let (d, k) = (self.dim, self.outputs.len());
        let n = points.len().checked_div(d).unwrap_or(0);
        regs.resize(self.n_regs.max(1), [0.0; L]);
        for &(r, v) in &self.consts {
            regs[r as usize] = [v; L];
        }
        let mut start = 0;
        while start < n {
            let lanes = L.min(n - start);
            load(&mut regs[..d], &points[start * d..(start + lanes) * d]);
            self.run(regs);
            store(
                regs,
                &self.out_regs,
                &mut out[start * k..(start + lanes) * k],
            );
            start += lanes;
        }
    }

    /// Runs every instruction over all lanes.
    fn run<const L: usize>(&self, regs: &mut [[f64; L]]) {
        let base = regs.as_mut_ptr();
        let n = regs.len();
        for ins in &self.instrs {
            let dst = ins.dst as usize;
            let (ra, rb) = ins.core.inputs();
            let (ra, rb) = (ra as usize, rb as usize);
            assert!(dst < n && ra < n && rb < n && dst != ra && dst != rb);
            // SAFETY: all three indices are in bounds, and the register allocator never gives
            // an instruction a destination equal to one of its inputs, so `out` does not
            // alias `a` or `b` (checked just above).
            let (a, b, out) = unsafe { (&*base.add(ra), &*base.add(rb), &mut *base.add(dst)) };
            let post = ins.post;
            match ins.core {
                Core::Un(op, _) => match op {
                    Op1::Neg => apply(out, post, |j| -a[j]),
                    Op1::Abs => apply(out, post, |j| a[j].abs()),
                    Op1::Sqrt => apply(out, post, |j| a[j].sqrt()),
                    _ => apply(out, post, |j| op.apply(a[j])),
                },
                Core::PowI(_, n) => apply(out, post, |j| powi(a[j], n)),
                Core::BinK(op, _, c) => match op {
                    Op2::Add => apply(out, post, |j| a[j] + c),
                    Op2::Sub => apply(out, post, |j| a[j] - c),
                    Op2::Mul => apply(out, post, |j| a[j] * c),
                    Op2::Div => apply(out, post, |j| a[j] / c),
                    _ => apply(out, post, |j| op.apply(a[j], c)),
                },
                Core::KBin(op, c, _) => match op {
                    Op2::Add => apply(out, post, |j| c + a[j]),
                    Op2::Sub => apply(out, post, |j| c - a[j]),
                    Op2::Mul => apply(out, post, |j| c * a[j]),
                    Op2::Div => apply(out, post, |j| c / a[j]),
                    _ => apply(out, post, |j| op.apply(c, a[j])),
                },
                Core::Bin(op, x, y) => match (x.square, y.square) {
                    (false, false) => bin::<false, false, L>(out, a, b, op, post),
                    (true, false) => bin::<true, false, L>(out, a, b, op, post),
                    (false, true) => bin::<false, true, L>(out, a, b, op, post),
                    (true, true) => bin::<true, true, L>(out, a, b, op, post),
                },
            }
        }
    }
}

/// An operand of a fused binary operation: a register, squared first when `square` is set.
#[derive(Clone, Copy, Debug)]
struct Operand {
    at: u32,
    square: bool,
}

/// The operation of one instruction, over node indices while planning and registers after.
#[derive(Clone, Copy, Debug)]
enum Core {
    Un(Op1, u32),
    /// a^n for n other than 2 (a^2 is a product, or a squared operand of its reader).
    PowI(u32, i32),
    /// a op c
    BinK(Op2, u32, f64),
    /// c op a
    KBin(Op2, f64, u32),
    /// a op b, either operand squared first
    Bin(Op2, Operand, Operand),
}

impl Core {
    fn inputs(&self) -> (u32, u32) {
        match *self {
            Core::Un(_, a) | Core::PowI(a, _) | Core::BinK(_, a, _) | Core::KBin(_, _, a) => (a, a),
            Core::Bin(_, x, y) => (x.at, y.at),
        }
    }

    fn map(self, f: impl Fn(u32) -> u32) -> Core {
        match self {
            Core::Un(op, a) => Core::Un(op, f(a)),
            Core::PowI(a, n) => Core::PowI(f(a), n),
            Core::BinK(op, a, c) => Core::BinK(op, f(a), c),
            Core::KBin(op, c, a) => Core::KBin(op, c, f(a)),
            Core::Bin(op, x, y) => Core::Bin(
                op,
                Operand {
                    at: f(x.at),
                    square: x.square,
                },
                Operand {
                    at: f(y.at),
                    square: y.square,
                },
            ),
        }
    }
}

/// A constant step applied to an instruction's result before it is stored: r + c, r - c or
/// r * c. Fusing it changes no rounding: the same operations run in the same order.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Post {
    None,
    Add(f64),
    Sub(f64),
    Mul(f64),
}

/// One instruction: `dst = post(core(inputs))` over all lanes.
#[derive(Clone, Copy, Debug)]
struct Instr {
    core: Core,
    post: Post,
    dst: u32,
}

/// One planned instruction: the node whose value it produces, and what it computes from
/// earlier nodes.
struct Planned {
    node: u32,
    core: Core,
    post: Post,
}

/// Groups the DAG's operations into instructions. A square a^2 read once is folded into the
/// binary operation that reads it, and a following `+ c`, `- c` or `* c` into the instruction
/// whose single-use result it takes; this cuts the passes over the lane registers (the cost of
/// an interpreter) without changing a single rounding.
fn fuse(nodes: &[Node], outputs: &[u32]) -> Vec<Planned> {
    let mut uses = vec![0usize; nodes.len()];
    for n in nodes {
        match *n {
            Node::Un(_, a) | Node::PowI(a, _) => uses[a as usize] += 1,
            Node::Bin(_, a, b) => {
                uses[a as usize] += 1;
                uses[b as usize] += 1;
            }
            _ => {}
        }
    }
    for &o in outputs {
        uses[o as usize] += 2;
    }
    let is_const = |i: u32| matches!(nodes[i as usize], Node::Const(_));
    let const_of = |i: u32| match nodes[i as usize] {
        Node::Const(c) => c,
        _ => f64::NAN,
    };
    let single_square = |i: u32| match nodes[i as usize] {
        Node::PowI(a, 2) if uses[i as usize] == 1 => Some(a),
        _ => None,
    };
    // Where each node's value is produced: the index of its planned instruction.
    let mut planned_at: Vec<Option<usize>> = vec![None; nodes.len()];
    let mut plan: Vec<Planned> = Vec::new();
    // A single-use square read by a non-constant +, - or * is folded into that reader and
    // never materialised.
    let mut folded = vec![false; nodes.len()];
    for n in nodes {
        if let Node::Bin(Op2::Add | Op2::Sub | Op2::Mul, a, b) = *n {
            if !is_const(a) && !is_const(b) {
                for x in [a, b] {
                    if single_square(x).is_some() {
                        folded[x as usize] = true;
                    }
                }
            }
        }
    }
    for (i, n) in nodes.iter().enumerate() {
        let id = i as u32;
        if folded[i] {
            continue;
        }
        let core = match *n {
            Node::Var(_) | Node::Const(_) => continue,
            Node::Un(op, a) => Core::Un(op, a),
            Node::PowI(a, 2) => Core::Bin(
                Op2::Mul,
                Operand {
                    at: a,
                    square: false,
                },
                Operand {
                    at: a,
                    square: false,
                },
            ),
            Node::PowI(a, n) => Core::PowI(a, n),
            Node::Bin(op, a, b) if is_const(b) => {
                let c = const_of(b);
                // Fold `r op c` into the instruction producing r when r is read only here.
                if let (Some(t), true) = (planned_at[a as usize], uses[a as usize] == 1) {
                    if plan[t].post == Post::None {
                        let post = match op {
                            Op2::Add => Some(Post::Add(c)),
                            Op2::Sub => Some(Post::Sub(c)),
                            Op2::Mul => Some(Post::Mul(c)),
                            _ => None,
                        };
                        if let Some(post) = post {
                            plan[t].post = post;
                            plan[t].node = id;
                            planned_at[a as usize] = None;
                            planned_at[i] = Some(t);
                            continue;
                        }
                    }
                }
                Core::BinK(op, a, c)
            }
            Node::Bin(op, a, b) if is_const(a) => Core::KBin(op, const_of(a), b),
            Node::Bin(op, a, b) => {
                let operand = |x: u32| {
                    if matches!(op, Op2::Add | Op2::Sub | Op2::Mul) && folded[x as usize] {
                        Operand {
                            at: single_square(x).expect("folded squares are single-use"),
                            square: true,
                        }
                    } else {
                        Operand {
                            at: x,
                            square: false,
                        }
                    }
                };
                Core::Bin(op, operand(a), operand(b))
            }
        };
        planned_at[i] = Some(plan.len());
        plan.push(Planned {
            node: id,
            core,
            post: Post::None,
        });
    }
    plan
}

/// Transposes rows of points into the variable registers (one register per coordinate).
fn load<const L: usize>(vars: &mut [[f64; L]], rows: &[f64]) {
    /// The same with the dimension known at compile time, so the inner loop unrolls.
    fn fixed<const D: usize, const L: usize>(vars: &mut [[f64; L]], rows: &[f64]) {
        let vars: &mut [[f64; L]; D] = vars.try_into().expect("D registers");
        for (j, p) in rows.chunks_exact(D).enumerate().take(L) {
            for v in 0..D {
                vars[v][j] = p[v];
            }
        }
    }
    match vars.len() {
        1 => fixed::<1, L>(vars, rows),
        2 => fixed::<2, L>(vars, rows),
        3 => fixed::<3, L>(vars, rows),
        4 => fixed::<4, L>(vars, rows),
        5 => fixed::<5, L>(vars, rows),
        6 => fixed::<6, L>(vars, rows),
        7 => fixed::<7, L>(vars, rows),
        8 => fixed::<8, L>(vars, rows),
        d => {
            for (j, p) in rows.chunks_exact(d).enumerate() {
                for (v, &x) in p.iter().enumerate() {
                    vars[v][j] = x;
                }
            }
        }
    }
}

/// Transposes the output registers `outs` into rows of `outs.len()` values.
fn store<const L: usize>(regs: &[[f64; L]], outs: &[u32], rows: &mut [f64]) {
    /// The same with the output count known at compile time.
    fn fixed<const K: usize, const L: usize>(regs: &[[f64; L]], outs: &[u32], rows: &mut [f64]) {
        let src: [&[f64; L]; K] = std::array::from_fn(|o| &regs[outs[o] as usize]);
        for (j, row) in rows.chunks_exact_mut(K).enumerate().take(L) {
            for o in 0..K {
                row[o] = src[o][j];
            }
        }
    }
    match outs.len() {
        1 => fixed::<1, L>(regs, outs, rows),
        2 => fixed::<2, L>(regs, outs, rows),
        3 => fixed::<3, L>(regs, outs, rows),
        4 => fixed::<4, L>(regs, outs, rows),
        k => {
            for (o, &r) in outs.iter().enumerate() {
                let r = &regs[r as usize];
                for (j, row) in rows.chunks_exact_mut(k).enumerate() {
                    row[o] = r[j];
                }
            }
        }
    }
}

#[inline(always)]
fn apply<const L: usize>(out: &mut [f64; L], post: Post, f: impl Fn(usize) -> f64) {
    match post {
        Post::None => (0..L).for_each(|j| out[j] = f(j)),
        Post::Add(c) => (0..L).for_each(|j| out[j] = f(j) + c),
        Post::Sub(c) => (0..L).for_each(|j| out[j] = f(j) - c),
        Post::Mul(c) => (0..L).for_each(|j| out[j] = f(j) * c),
    }
}

#[inline(always)]
fn operand<const SQUARE: bool, const L: usize>(a: &[f64; L], j: usize) -> f64 {
    if SQUARE {
        a[j] * a[j]
    } else {
        a[j]
    }
}

#[inline(always)]
fn bin<const SA: bool, const SB: bool, const L: usize>(
    out: &mut [f64; L],
    a: &[f64; L],
    b: &[f64; L],
    op: Op2,
    post: Post,
) {
    let x = |j| operand::<SA, L>(a, j);
    let y = |j| operand::<SB, L>(b, j);
    match op {
        Op2::Add => apply(out, post, |j| x(j) + y(j)),
        Op2::Sub => apply(out, post, |j| x(j) - y(j)),
        Op2::Mul => apply(out, post, |j| x(j) * y(j)),
        Op2::Div => apply(out, post, |j| x(j) / y(j)),
        _ => apply(out, post, |j| op.apply(x(j), y(j))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::ast::Expr;

    fn square(i: usize) -> Expr {
        Expr::powi(Expr::Var(i), 2)
    }

    #[test]
    fn squares_and_constant_steps_fuse_into_one_instruction() {
        // x^2 + y^2 - 1: one pass over the lanes instead of four.
        let e = Expr::Bin(
            Op2::Sub,
            Box::new(Expr::Bin(
                Op2::Add,
                Box::new(square(0)),
                Box::new(square(1)),
            )),
            Box::new(Expr::Num(1.0)),
        );
        let p = Program::compile(std::slice::from_ref(&e), 2);
        assert_eq!(p.instrs.len(), 1);
        let mut out = [0.0];
        p.eval(&[0.5, 2.0], &mut out);
        assert_eq!(out[0], 0.5 * 0.5 + 2.0 * 2.0 - 1.0);
        // A square read twice is computed once and not folded.
        let twice = Expr::Bin(Op2::Mul, Box::new(square(0)), Box::new(square(0)));
        let p = Program::compile(&[twice], 1);
        assert_eq!(p.instrs.len(), 2);
    }
}
