//! Expressions compiled to a flat instruction list over a shared DAG (common sub-expressions
//! merged), evaluated in f64 over many points at once: each instruction runs over a chunk of
//! points before the next starts, so the loop bodies vectorise and nothing walks a tree.
//! The WGSL emitter walks the same DAG, so CPU and GPU compute the same operations in the same
//! order.

use std::collections::HashMap;

use crate::expr::ast::{powi, Expr, Op1, Op2};

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
#[derive(Clone, Debug)]
pub struct Program {
    dim: usize,
    nodes: Vec<Node>,
    outputs: Vec<u32>,
    /// Register of each node (variables and constants have their own, fixed).
    reg: Vec<u32>,
    n_regs: usize,
}

/// Scratch registers for [`Program::eval_batch`]; reuse one per thread.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    regs: Vec<[f64; LANES]>,
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

    fn add(&mut self, e: &Expr) -> u32 {
        let node = match e {
            Expr::Num(v) => Node::Const(*v),
            Expr::Var(i) => Node::Var(*i),
            Expr::Un(op, a) => {
                let a = self.add(a);
                Node::Un(*op, a)
            }
            Expr::Bin(op, a, b) => {
                let a = self.add(a);
                let b = self.add(b);
                Node::Bin(*op, a, b)
            }
            Expr::PowI(a, n) => {
                let a = self.add(a);
                Node::PowI(a, *n)
            }
        };
        self.intern(node)
    }
}

impl Program {
    /// Compiles `exprs` (in variables x_1..x_dim) into one program with one output each.
    pub fn compile(exprs: &[Expr], dim: usize) -> Program {
        let mut b = Builder {
            nodes: Vec::new(),
            index: HashMap::new(),
        };
        // Variables first, so that register i holds x_i.
        for i in 0..dim {
            b.intern(Node::Var(i));
        }
        let outputs: Vec<u32> = exprs.iter().map(|e| b.add(e)).collect();
        let nodes = b.nodes;

        // Register allocation: variables and constants keep theirs; an operation's register is
        // freed after its last use (outputs live to the end).
        let mut last_use = vec![0usize; nodes.len()];
        for (i, n) in nodes.iter().enumerate() {
            match *n {
                Node::Un(_, a) | Node::PowI(a, _) => last_use[a as usize] = i,
                Node::Bin(_, a, c) => {
                    last_use[a as usize] = i;
                    last_use[c as usize] = i;
                }
                _ => {}
            }
        }
        for &o in &outputs {
            last_use[o as usize] = usize::MAX;
        }
        let mut reg = vec![0u32; nodes.len()];
        let mut n_regs = 0u32;
        let mut free: Vec<u32> = Vec::new();
        for (i, n) in nodes.iter().enumerate() {
            if matches!(n, Node::Var(_) | Node::Const(_)) {
                reg[i] = n_regs;
                n_regs += 1;
            }
        }
        for (i, n) in nodes.iter().enumerate() {
            let args: [Option<u32>; 2] = match *n {
                Node::Un(_, a) | Node::PowI(a, _) => [Some(a), None],
                Node::Bin(_, a, c) => [Some(a), Some(c)],
                _ => continue,
            };
            // The destination is chosen before this node's arguments are freed, so it never
            // aliases an input (run() relies on this).
            reg[i] = free.pop().unwrap_or_else(|| {
                n_regs += 1;
                n_regs - 1
            });
            for a in args.into_iter().flatten() {
                let a = a as usize;
                if last_use[a] == i && !matches!(nodes[a], Node::Var(_) | Node::Const(_)) {
                    last_use[a] = usize::MAX - 1; // freed once even if used twice here
                    free.push(reg[a]);
                }
            }
        }
        Program {
            dim,
            nodes,
            outputs,
            reg,
            n_regs: n_regs as usize,
        }
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
        scratch.regs.resize(self.n_regs.max(1), [0.0; LANES]);
        let regs = &mut scratch.regs;
        for (i, node) in self.nodes.iter().enumerate() {
            if let Node::Const(v) = node {
                regs[self.reg[i] as usize] = [*v; LANES];
            }
        }
        let mut start = 0;
        while start < n {
            let lanes = LANES.min(n - start);
            for (j, p) in points[start * d..(start + lanes) * d]
                .chunks_exact(d)
                .enumerate()
            {
                for (v, &x) in p.iter().enumerate() {
                    regs[v][j] = x;
                }
            }
            self.run(regs);
            let rows = &mut out[start * k..(start + lanes) * k];
            for (o, &node) in self.outputs.iter().enumerate() {
                let r = &regs[self.reg[node as usize] as usize];
                for (j, row) in rows.chunks_exact_mut(k).enumerate() {
                    row[o] = r[j];
                }
            }
            start += lanes;
        }
    }

    #[inline]
    fn is_const(&self, node: u32) -> bool {
        matches!(self.nodes[node as usize], Node::Const(_))
    }

    #[inline]
    fn const_value(&self, node: u32) -> f64 {
        match self.nodes[node as usize] {
            Node::Const(c) => c,
            _ => f64::NAN,
        }
    }

    /// Runs every instruction over all lanes.
    fn run(&self, regs: &mut [[f64; LANES]]) {
        let base = regs.as_mut_ptr();
        let n = regs.len();
        for (i, node) in self.nodes.iter().enumerate() {
            let dst = self.reg[i] as usize;
            let arg = |a: u32| self.reg[a as usize] as usize;
            let (ra, rb) = match *node {
                Node::Var(_) | Node::Const(_) => continue,
                Node::Un(_, a) | Node::PowI(a, _) => (arg(a), arg(a)),
                Node::Bin(_, a, b) => (arg(a), arg(b)),
            };
            assert!(dst < n && ra < n && rb < n && dst != ra && dst != rb);
            // SAFETY: all three indices are in bounds, and the register allocator never gives
            // an instruction a destination equal to one of its inputs, so `out` does not
            // alias `a` or `b` (checked just above).
            let (a, b, out) = unsafe { (&*base.add(ra), &*base.add(rb), &mut *base.add(dst)) };
            match *node {
                Node::Un(op, _) => match op {
                    Op1::Neg => lanes1(out, a, |x| -x),
                    Op1::Abs => lanes1(out, a, f64::abs),
                    Op1::Sqrt => lanes1(out, a, f64::sqrt),
                    _ => lanes1(out, a, |x| op.apply(x)),
                },
                Node::Bin(op, _, nb) if self.is_const(nb) => {
                    let c = self.const_value(nb);
                    match op {
                        Op2::Add => lanes1(out, a, |x| x + c),
                        Op2::Sub => lanes1(out, a, |x| x - c),
                        Op2::Mul => lanes1(out, a, |x| x * c),
                        Op2::Div => lanes1(out, a, |x| x / c),
                        _ => lanes1(out, a, |x| op.apply(x, c)),
                    }
                }
                Node::Bin(op, na, _) if self.is_const(na) => {
                    let c = self.const_value(na);
                    match op {
                        Op2::Add => lanes1(out, b, |y| c + y),
                        Op2::Sub => lanes1(out, b, |y| c - y),
                        Op2::Mul => lanes1(out, b, |y| c * y),
                        Op2::Div => lanes1(out, b, |y| c / y),
                        _ => lanes1(out, b, |y| op.apply(c, y)),
                    }
                }
                Node::Bin(op, _, _) => match op {
                    Op2::Add => lanes2(out, a, b, |x, y| x + y),
                    Op2::Sub => lanes2(out, a, b, |x, y| x - y),
                    Op2::Mul => lanes2(out, a, b, |x, y| x * y),
                    Op2::Div => lanes2(out, a, b, |x, y| x / y),
                    _ => lanes2(out, a, b, |x, y| op.apply(x, y)),
                },
                Node::PowI(_, 2) => lanes1(out, a, |x| x * x),
                Node::PowI(_, n) => lanes1(out, a, |x| powi(x, n)),
                _ => {}
            }
        }
    }
}

#[inline(always)]
fn lanes1(out: &mut [f64; LANES], a: &[f64; LANES], f: impl Fn(f64) -> f64) {
    for j in 0..LANES {
        out[j] = f(a[j]);
    }
}

#[inline(always)]
fn lanes2(out: &mut [f64; LANES], a: &[f64; LANES], b: &[f64; LANES], f: impl Fn(f64, f64) -> f64) {
    for j in 0..LANES {
        out[j] = f(a[j], b[j]);
    }
}
