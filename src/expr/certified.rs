//! Certified values: f evaluated in a device's arithmetic (f32 or f64, its own elementary
//! functions, contracted or not) together with a bound `e` such that the CPU's f64 value and
//! the exact value of the expression both lie within `e` of the device's value.
//!
//! A [`Cv`] `(v, e)` at a node of the DAG ([`Program`]) means: the exact value of the node at
//! the exact input, and the value the CPU computes for it (IEEE f64, the same DAG in the same
//! order, its library's elementary functions), are both within `e` of `v`. Each rule below
//! bounds the result from its operands' bounds, the device's rounding of the operation, and
//! (at the language's own operations) the CPU's rounding; functions the CPU calls directly
//! (`tan`, `asinh`, `pow`, ...) are computed on the device from a few primitives (exp, ln,
//! sin, cos, atan2, sqrt) whose accuracy is claimed in [`Accuracy`], and the CPU's library
//! error is added at the end. Every computed bound is enlarged by [`Accuracy::grow`] for the
//! rounding of its own arithmetic. A bound that is not finite, or reaches
//! [`Accuracy::big`], means "unknown": the caller decides that value on the CPU.
//!
//! The same rules are written in WGSL in `shaders/certified.wgsl`; [`certified_eval`] is
//! their CPU twin, generic over the device's float type.

// `!(a < b)` is meant: a NaN must fail every test and so make the result unknown.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::expr::ast::{Op1, Op2};
use crate::expr::program::{Node, Program};

/// Unit roundoff of f64 (2^-53).
pub const U64: f64 = f64::EPSILON / 2.0;
/// Unit roundoff of f32 (2^-24).
pub const U32: f64 = f32::EPSILON as f64 / 2.0;

/// The unit roundoff to assume of a conforming device's f64 `+ - *`: that of f32. Vulkan
/// ("Precision and Operation of SPIR-V Instructions") promises double-precision operations
/// only "at least the precision of single precision"; an error of up to one f32 ulp (2 of
/// these units, rounding toward zero included) is what the margins built on it allow for.
pub const DEVICE_F64_UNIT: f64 = U32;

/// The CPU's claimed error for its library functions (sin, exp, pow, ...) in ulps: glibc
/// documents at most 2 for each one isomesh calls; twice that is assumed.
pub const CPU_FN_ULPS: f64 = 4.0;

/// The accuracy the certified evaluation assumes of a device (and of the CPU), in one place
/// for the Rust twin and the shader (whose constants are written from this).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accuracy {
    /// Relative error of + - * on the device: one ulp (2 unit roundoffs), since the
    /// specifications leave the rounding mode open (to nearest or toward zero).
    pub unit: f64,
    /// Unit roundoff of the CPU's f64 operations.
    pub cpu: f64,
    /// The CPU's relative error for a library function (`CPU_FN_ULPS` ulps).
    pub cpu_fn: f64,
    /// Absolute error any operation may add near zero (flushed subnormals on either side).
    pub tiny: f64,
    /// Factor every computed bound is multiplied by, for the rounding of the bound's own
    /// arithmetic (at most about a dozen operations a rule).
    pub grow: f64,
    /// Bounds at or above this mean "unknown" (a power of two: exact in f32 and f64).
    pub big: f64,
    /// Relative error of the device's division (2.5 ulp in WGSL and Vulkan),
    pub div: f64,
    /// for divisors of magnitude within this range (outside it, any result).
    pub div_range: [f64; 2],
    /// Relative error of the device's sqrt (WGSL: inherited from 1 / inverseSqrt),
    pub sqrt: f64,
    /// for arguments within this range (so that the division meets its claim).
    pub sqrt_range: [f64; 2],
    /// The device's exp: relative error `exp0 + exp1 |x|`, for |x| at most `exp_max` (where
    /// f32's exp is normal, so that no flushed result escapes the claim).
    pub exp0: f64,
    /// See `exp0`.
    pub exp1: f64,
    /// See `exp0`.
    pub exp_max: f64,
    /// The device's ln: error `ln_rel |y| + ln_abs`, for arguments in `ln_range`.
    pub ln_rel: f64,
    /// See `ln_rel`.
    pub ln_abs: f64,
    /// Arguments for which the device's ln meets its claim.
    pub ln_range: [f64; 2],
    /// The device's sin and cos: absolute error `trig_abs + trig_rel |x|`, for |x| at most
    /// `trig_max`.
    pub trig_abs: f64,
    /// See `trig_abs`.
    pub trig_rel: f64,
    /// See `trig_abs`.
    pub trig_max: f64,
    /// The device's atan2: error `atan_rel |y| + atan_abs`, for max(|x|, |y|) within
    /// `atan_range`.
    pub atan_rel: f64,
    /// See `atan_rel`.
    pub atan_abs: f64,
    /// See `atan_rel`.
    pub atan_range: [f64; 2],
    /// Arguments of the f32 built-ins below this may be flushed to zero, sign and all.
    pub builtin_flush: f64,
}

impl Accuracy {
    /// A device computing in f32 with WGSL's built-in functions, at the accuracy the WGSL
    /// and Vulkan specifications require of them (sin and cos after the shader's own
    /// reduction to [-pi, pi]); outside the ranges they bound, values are unknown.
    pub fn f32() -> Accuracy {
        let u = U32;
        Accuracy {
            unit: 2.0 * u,
            cpu: U64,
            cpu_fn: 2.0 * CPU_FN_ULPS * U64,
            tiny: 2.0f64.powi(-125),
            grow: 1.0 + 64.0 * u,
            big: 2.0f64.powi(120),
            div: 5.0 * u,
            div_range: [2.0f64.powi(-126), 2.0f64.powi(126)],
            sqrt: 12.0 * u,
            sqrt_range: [2.0f64.powi(-124), 2.0f64.powi(124)],
            // 3 + 2|x| ulp.
            exp0: 6.0 * u,
            exp1: 4.0 * u,
            exp_max: 87.0,
            // 3 ulp outside [0.5, 2], absolute 2^-21 inside.
            ln_rel: 6.0 * u,
            ln_abs: 2.0f64.powi(-21),
            ln_range: [2.0f64.powi(-125), 2.0f64.powi(126)],
            // Absolute 2^-11 on [-pi, pi], plus the reduction's rounding.
            trig_abs: 2.0f64.powi(-11),
            trig_rel: 8.0 * u,
            trig_max: 1e5,
            // 4096 ulp, and a flushed subnormal coordinate (at most 2^-126 / 2^-100).
            atan_rel: 8192.0 * u,
            atan_abs: 2.0f64.powi(-25),
            atan_range: [2.0f64.powi(-100), 2.0f64.powi(100)],
            builtin_flush: 2.0f64.powi(-126),
        }
    }

    /// A device computing in f64: only what the specifications promise, which is single
    /// precision for every operation ([`DEVICE_F64_UNIT`]), f64's range, and no f64
    /// elementary functions at all. The shader takes exp, ln, sin, cos and atan2 from the
    /// f32 built-ins on arguments converted to f32: their bounds are f32's plus that
    /// conversion (an error of 2u |x| in the argument of exp, sin and cos, 2u relative in
    /// those of ln and atan2).
    pub fn f64() -> Accuracy {
        let f = Accuracy::f32();
        let u = DEVICE_F64_UNIT;
        Accuracy {
            unit: 2.0 * u,
            tiny: 2.0f64.powi(-1020),
            big: 2.0f64.powi(995),
            exp0: f.exp0 + u,
            exp1: f.exp1 + 3.0 * u,
            ln_abs: f.ln_abs + 3.0 * u,
            trig_abs: f.trig_abs + 2.0f64.powi(-120),
            trig_rel: f.trig_rel + 3.0 * u,
            atan_abs: f.atan_abs + 3.0 * u,
            ..f
        }
    }

    /// Whether `x` lies within `range` (NaN does not).
    pub fn within(x: f64, range: [f64; 2]) -> bool {
        x >= range[0] && x <= range[1]
    }
}

/// A device float type: the operations the rules use, as the device computes them.
pub trait DeviceReal: Copy + PartialOrd + std::fmt::Debug {
    /// Rounds an f64 to this type.
    fn of(x: f64) -> Self;
    /// Widens to f64 (exact).
    fn wide(self) -> f64;
    /// The smallest value of this type at or above `x` (x itself in f64).
    fn of_up(x: f64) -> Self;
    /// The unit roundoff of this type (IEEE arithmetic, as on the CPU).
    const UNIT: f64;
    /// The unit roundoff the specifications promise for a device's `+ - *` in this type
    /// (f32's also for f64: [`DEVICE_F64_UNIT`]).
    const SPEC_UNIT: f64;
    /// The smallest positive normal value of this type.
    const MIN_NORMAL: f64;
    /// a + b.
    fn add(self, b: Self) -> Self;
    /// a - b.
    fn sub(self, b: Self) -> Self;
    /// a * b.
    fn mul(self, b: Self) -> Self;
    /// a / b.
    fn div(self, b: Self) -> Self;
    /// |a|.
    fn abs(self) -> Self;
    /// -a (a sign flip: exact on every device).
    fn neg(self) -> Self;
    /// sqrt a.
    fn sqrt(self) -> Self;
    /// exp a.
    fn exp(self) -> Self;
    /// ln a.
    fn ln(self) -> Self;
    /// sin a.
    fn sin(self) -> Self;
    /// cos a.
    fn cos(self) -> Self;
    /// atan2(a, x).
    fn atan2(self, x: Self) -> Self;
}

macro_rules! device_real {
    ($t:ty, $spec:expr) => {
        impl DeviceReal for $t {
            fn of(x: f64) -> Self {
                x as $t
            }
            fn wide(self) -> f64 {
                self as f64
            }
            fn of_up(x: f64) -> Self {
                let r = x as $t;
                if (r as f64) >= x || r.is_nan() {
                    r
                } else if r == 0.0 {
                    <$t>::from_bits(1)
                } else if r > 0.0 {
                    <$t>::from_bits(r.to_bits() + 1)
                } else {
                    <$t>::from_bits(r.to_bits() - 1)
                }
            }
            const UNIT: f64 = <$t>::EPSILON as f64 / 2.0;
            const SPEC_UNIT: f64 = $spec;
            const MIN_NORMAL: f64 = <$t>::MIN_POSITIVE as f64;
            fn add(self, b: Self) -> Self {
                self + b
            }
            fn sub(self, b: Self) -> Self {
                self - b
            }
            fn mul(self, b: Self) -> Self {
                self * b
            }
            fn div(self, b: Self) -> Self {
                self / b
            }
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            fn neg(self) -> Self {
                -self
            }
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            fn ln(self) -> Self {
                <$t>::ln(self)
            }
            fn sin(self) -> Self {
                <$t>::sin(self)
            }
            fn cos(self) -> Self {
                <$t>::cos(self)
            }
            fn atan2(self, x: Self) -> Self {
                <$t>::atan2(self, x)
            }
        }
    };
}
device_real!(f32, U32);
device_real!(f64, DEVICE_F64_UNIT);

/// A certified value: the device's value `v` and the bound `e` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cv<R> {
    /// The device's value.
    pub v: R,
    /// The bound on the distance to the exact and to the CPU's value.
    pub e: R,
}

impl<R: DeviceReal> Cv<R> {
    /// A value known exactly.
    pub fn exact(v: R) -> Self {
        Cv { v, e: R::of(0.0) }
    }

    /// Whether the bound is usable (finite and below [`Accuracy::big`]).
    pub fn known(&self, acc: &Accuracy) -> bool {
        self.v.wide().abs() < acc.big && self.e.wide() < acc.big
    }

    /// The sign the CPU's value certainly has: 1 or -1, or 0 when it is not certain (the
    /// bound reaches zero, or is unknown).
    #[cfg(any(test, feature = "internals"))]
    pub fn sign(&self, acc: &Accuracy) -> i32 {
        if !self.known(acc) {
            0
        } else if self.v.sub(self.e) > R::of(0.0) {
            1
        } else if self.v.add(self.e) < R::of(0.0) {
            -1
        } else {
            0
        }
    }
}

/// The rules, in the device's type R: each mirrors a function of `shaders/certified.wgsl`.
pub struct Rules<R> {
    acc: Accuracy,
    unit: R,
    cpu: R,
    cpu_fn: R,
    tiny: R,
    grow: R,
    big: R,
}

impl<R: DeviceReal> Rules<R> {
    /// The rules under `acc`.
    pub fn new(acc: &Accuracy) -> Self {
        Rules {
            acc: *acc,
            unit: R::of(acc.unit),
            cpu: R::of(acc.cpu),
            cpu_fn: R::of(acc.cpu_fn),
            tiny: R::of(acc.tiny),
            grow: R::of(acc.grow),
            big: R::of(acc.big),
        }
    }

    /// The accuracy these rules assume.
    #[cfg(any(test, feature = "internals"))]
    pub fn accuracy(&self) -> &Accuracy {
        &self.acc
    }

    fn c(&self, x: f64) -> R {
        R::of(x)
    }

    /// Whether x lies within `range` (NaN does not): where the device's operation meets
    /// its claim.
    fn inside(&self, x: R, range: [f64; 2]) -> bool {
        x >= self.c(range[0]) && x <= self.c(range[1])
    }

    /// `v` with bound `e` enlarged by `grow` (and `tiny`); unknown when not finite.
    fn done(&self, v: R, e: R) -> Cv<R> {
        let e = e.mul(self.grow).add(self.tiny);
        // NaN fails both comparisons.
        if e < self.big && v.abs() < self.big {
            Cv { v, e }
        } else {
            self.unknown(v)
        }
    }

    fn unknown(&self, v: R) -> Cv<R> {
        Cv { v, e: self.big }
    }

    /// Whether both operands have usable bounds: every rule's result is unknown otherwise
    /// (an unknown operand may be NaN on the CPU, and a product with a small factor could
    /// make an unknown bound look usable).
    fn known2(&self, a: Cv<R>, b: Cv<R>) -> bool {
        a.known(&self.acc) && b.known(&self.acc)
    }

    /// The CPU's rounding unit when the CPU performs this operation itself, else 0.
    fn cpu_unit(&self, cpu: bool) -> R {
        if cpu {
            self.cpu
        } else {
            self.c(0.0)
        }
    }

    /// a + b.
    pub fn add(&self, a: Cv<R>, b: Cv<R>, cpu: bool) -> Cv<R> {
        self.sum(a, b, a.v.add(b.v), cpu)
    }

    /// a - b.
    pub fn sub(&self, a: Cv<R>, b: Cv<R>, cpu: bool) -> Cv<R> {
        self.sum(a, b, a.v.sub(b.v), cpu)
    }

    fn sum(&self, a: Cv<R>, b: Cv<R>, v: R, cpu: bool) -> Cv<R> {
        if !self.known2(a, b) {
            return self.unknown(v);
        }
        let eab = a.e.add(b.e);
        let size = a.v.abs().add(b.v.abs()).add(eab);
        let e = eab.add(self.unit.add(self.cpu_unit(cpu)).mul(size));
        self.done(v, e)
    }

    /// a * b.
    pub fn mul(&self, a: Cv<R>, b: Cv<R>, cpu: bool) -> Cv<R> {
        if !self.known2(a, b) {
            return self.unknown(a.v.mul(b.v));
        }
        // Operands widened by `tiny`: a device may flush a subnormal operand to zero.
        let (ae, be) = (a.e.add(self.tiny), b.e.add(self.tiny));
        let (ma, mb) = (a.v.abs().add(ae), b.v.abs().add(be));
        let prop = a.v.abs().mul(be).add(b.v.abs().mul(ae)).add(ae.mul(be));
        let e = prop.add(self.unit.add(self.cpu_unit(cpu)).mul(ma.mul(mb)));
        self.done(a.v.mul(b.v), e)
    }

    /// a / b; unknown when b's bound reaches 0, or b or the bound's divisor leaves the
    /// range where the device's division meets its claim.
    pub fn div(&self, a: Cv<R>, b: Cv<R>, cpu: bool) -> Cv<R> {
        let q = a.v.div(b.v);
        if !self.known2(a, b) {
            return self.unknown(q);
        }
        let (ae, be) = (a.e.add(self.tiny), b.e.add(self.tiny));
        let bb = b.v.abs();
        let den = bb.sub(be);
        let range = self.acc.div_range;
        if !(den >= self.c(range[0])) || !(bb <= self.c(range[1])) {
            return self.unknown(q);
        }
        // |a/b - A/B| <= (|a| e_b + |b| e_a) / (|b| (|b| - e_b)) = |a/b| e_b/den + e_a/den,
        // with |a/b| from the device's quotient; no product of magnitudes, which could
        // overflow to infinity and vanish from the bound.
        let qa = q.abs().mul(self.c(1.0 + 2.0 * self.acc.div));
        let prop = qa.mul(be.div(den)).add(ae.div(den));
        let round = self.c(self.acc.div).add(self.cpu_unit(cpu));
        let e = prop.add(round.mul(a.v.abs().add(ae)).div(den));
        self.done(q, e)
    }

    /// sqrt a; unknown when a's bound leaves the range where the device's sqrt meets its
    /// claim (below it, sqrt 0 included: 1 / inverseSqrt(0) promises nothing).
    pub fn sqrt(&self, a: Cv<R>, cpu: bool) -> Cv<R> {
        let y = a.v.sqrt();
        let range = self.acc.sqrt_range;
        if !a.known(&self.acc) || !(a.v.sub(a.e) >= self.c(range[0])) || !(a.v <= self.c(range[1]))
        {
            return self.unknown(y);
        }
        let s = self.c(self.acc.sqrt);
        // |sqrt x - sqrt y| <= |x - y| / sqrt(x), and <= sqrt|x - y| (the device's sqrt of
        // the bound, where it meets its claim).
        let one = self.c(1.0);
        let by_slope = a.e.div(y.mul(one.sub(s)));
        let prop = if a.e == self.c(0.0) {
            self.c(0.0)
        } else if !(a.e >= self.c(range[0])) {
            by_slope
        } else {
            let by_root = a.e.sqrt().mul(one.add(s));
            if by_slope < by_root {
                by_slope
            } else {
                by_root
            }
        };
        let e = prop.add(s.add(self.cpu_unit(cpu)).mul(y.abs().add(prop)));
        self.done(y, e)
    }

    /// The CPU's library error for the language's function whose device value is `r`.
    fn cpu_fn(&self, r: Cv<R>) -> Cv<R> {
        if !r.known(&self.acc) {
            return r;
        }
        let e = r.e.add(self.cpu_fn.mul(r.v.abs().add(r.e)));
        self.done(r.v, e)
    }

    /// exp a, as the device computes it.
    fn exp_raw(&self, a: Cv<R>) -> Cv<R> {
        let y = a.v.exp();
        let top = a.v.add(a.e);
        let max = self.c(self.acc.exp_max);
        if !a.known(&self.acc)
            || !(a.v.abs() <= max)
            || !(top <= max)
            || !(a.v.sub(a.e) >= max.neg())
        {
            return self.unknown(y);
        }
        let claim = |x: R| {
            self.c(self.acc.exp0)
                .add(self.c(self.acc.exp1).mul(x.abs()))
        };
        // |exp(x + h) - exp x| <= exp(x + |h|) |h|, the device's exp(top) within its claim.
        let one = self.c(1.0);
        let prop = top.exp().mul(one.add(claim(top))).mul(a.e);
        let e = prop.add(claim(a.v).mul(y.abs()));
        self.done(y, e)
    }

    /// ln a, as the device computes it; unknown when a's bound reaches 0 or a is outside
    /// the device's range.
    fn ln_raw(&self, a: Cv<R>) -> Cv<R> {
        let y = a.v.ln();
        let lo = a.v.sub(a.e);
        let [r0, r1] = self.acc.ln_range;
        if !a.known(&self.acc)
            || !(lo >= self.c(self.acc.div_range[0]))
            || !(a.v >= self.c(r0))
            || !(a.v <= self.c(r1))
        {
            return self.unknown(y);
        }
        let prop = a.e.div(lo);
        let own = self
            .c(self.acc.ln_rel)
            .mul(y.abs())
            .add(self.c(self.acc.ln_abs));
        self.done(y, prop.add(own))
    }

    /// sin a (`cos` false) or cos a, as the device computes them.
    fn trig_raw(&self, a: Cv<R>, cos: bool) -> Cv<R> {
        let y = if cos { a.v.cos() } else { a.v.sin() };
        // An unknown argument may be NaN on the CPU: the result is unknown too, although
        // sin and cos of any two numbers differ by at most 2.
        if !a.known(&self.acc) || !(a.v.abs() <= self.c(self.acc.trig_max)) {
            return self.unknown(y);
        }
        let own = self
            .c(self.acc.trig_abs)
            .add(self.c(self.acc.trig_rel).mul(a.v.abs()));
        let two = self.c(2.0);
        let prop = if a.e < two { a.e } else { two };
        self.done(y, prop.add(own))
    }

    /// atan2(y, x), as the device computes it; unknown when the bounds reach the origin or
    /// the branch cut (the negative x axis).
    fn atan2_raw(&self, y: Cv<R>, x: Cv<R>) -> Cv<R> {
        let t = y.v.atan2(x.v);
        // |p| >= max(|x|, |y|), exactly (a square could overflow).
        let r = if x.v.abs() < y.v.abs() {
            y.v.abs()
        } else {
            x.v.abs()
        };
        let delta = y.e.add(x.e);
        let zero = self.c(0.0);
        // Near the cut the sign of y decides; one the built-in may flush is not known.
        let cut = x.v.sub(x.e) < zero && !(y.v.abs() > y.e.add(self.c(self.acc.builtin_flush)));
        if !self.known2(y, x) || !(delta < r) || cut || !self.inside(r, self.acc.atan_range) {
            return self.unknown(t);
        }
        // The angle between p and q with |p - q| <= delta < |p| is at most
        // asin(delta / |p|) <= (pi / 2) delta / |p|.
        let prop = self.c(std::f64::consts::FRAC_PI_2).mul(delta).div(r);
        let own = self
            .c(self.acc.atan_rel)
            .mul(t.abs())
            .add(self.c(self.acc.atan_abs));
        self.done(t, prop.add(own))
    }

    /// The language's one-argument operation `op`.
    pub fn un(&self, op: Op1, a: Cv<R>) -> Cv<R> {
        let one = Cv::exact(self.c(1.0));
        match op {
            Op1::Neg => Cv {
                v: a.v.neg(),
                e: a.e,
            },
            Op1::Abs => Cv {
                v: a.v.abs(),
                e: a.e,
            },
            Op1::Sign => {
                let zero = self.c(0.0);
                if !a.known(&self.acc) {
                    self.unknown(zero)
                } else if a.v.sub(a.e) > zero {
                    Cv::exact(self.c(1.0))
                } else if a.v.add(a.e) < zero {
                    Cv::exact(self.c(-1.0))
                } else if a.v == zero && a.e == zero {
                    Cv::exact(zero)
                } else {
                    Cv {
                        v: zero,
                        e: self.c(1.0),
                    }
                }
            }
            Op1::Sqrt => self.sqrt(a, true),
            Op1::Exp => self.cpu_fn(self.exp_raw(a)),
            Op1::Ln => self.cpu_fn(self.ln_raw(a)),
            Op1::Sin => self.cpu_fn(self.trig_raw(a, false)),
            Op1::Cos => self.cpu_fn(self.trig_raw(a, true)),
            Op1::Tan => {
                let (s, c) = (self.trig_raw(a, false), self.trig_raw(a, true));
                self.cpu_fn(self.div(s, c, false))
            }
            Op1::Atan => self.cpu_fn(self.atan2_raw(a, one)),
            Op1::Asin | Op1::Acos => {
                // asin a = atan2(a, sqrt(1 - a^2)), acos a = atan2(sqrt(1 - a^2), a).
                let sq = self.mul(a, a, false);
                let root = self.sqrt(self.sub(one, sq, false), false);
                let t = if op == Op1::Asin {
                    self.atan2_raw(a, root)
                } else {
                    self.atan2_raw(root, a)
                };
                self.cpu_fn(t)
            }
            Op1::Sinh | Op1::Cosh => {
                // (e^a -+ e^-a) / 2, with e^-a = 1 / e^a.
                let ex = self.exp_raw(if op == Op1::Sinh {
                    a
                } else {
                    self.un(Op1::Abs, a)
                });
                let inv = self.div(one, ex, false);
                let s = if op == Op1::Sinh {
                    self.sub(ex, inv, false)
                } else {
                    self.add(ex, inv, false)
                };
                self.cpu_fn(self.mul(s, Cv::exact(self.c(0.5)), false))
            }
            Op1::Tanh => {
                // sign(a) (1 - t) / (1 + t), t = e^{-2|a|}: no overflow for large |a|.
                let m = self.mul(self.un(Op1::Abs, a), Cv::exact(self.c(-2.0)), false);
                let t = self.exp_raw(m);
                let q = self.div(self.sub(one, t, false), self.add(one, t, false), false);
                let s = self.un(Op1::Sign, a);
                self.cpu_fn(self.mul(s, q, false))
            }
        }
    }

    /// The language's two-argument operation `op`.
    pub fn bin(&self, op: Op2, a: Cv<R>, b: Cv<R>) -> Cv<R> {
        match op {
            Op2::Add => self.add(a, b, true),
            Op2::Sub => self.sub(a, b, true),
            Op2::Mul => self.mul(a, b, true),
            Op2::Div => self.div(a, b, true),
            Op2::Min | Op2::Max => {
                if !self.known2(a, b) {
                    return self.unknown(a.v);
                }
                let v = if (op == Op2::Min) == (a.v < b.v) {
                    a.v
                } else {
                    b.v
                };
                let e = if a.e < b.e { b.e } else { a.e };
                self.done(v, e)
            }
            Op2::Pow => {
                // a^b = exp(b ln a), for a certainly positive.
                let l = self.ln_raw(a);
                self.cpu_fn(self.exp_raw(self.mul(b, l, false)))
            }
            Op2::Atan2 => self.cpu_fn(self.atan2_raw(a, b)),
        }
    }

    /// a^n by the CPU's squaring sequence ([`crate::expr::ast::powi`]).
    pub fn powi(&self, a: Cv<R>, n: i32) -> Cv<R> {
        let mut e = n.unsigned_abs();
        let mut base = a;
        let mut acc: Option<Cv<R>> = None;
        while e > 0 {
            if e & 1 == 1 {
                acc = Some(match acc {
                    None => base,
                    Some(p) => self.mul(p, base, true),
                });
            }
            e >>= 1;
            if e > 0 {
                base = self.mul(base, base, true);
            }
        }
        let one = Cv::exact(self.c(1.0));
        let acc = acc.unwrap_or(one);
        if n < 0 {
            self.div(one, acc, true)
        } else {
            acc
        }
    }

    /// A constant as the device holds it, with its rounding as the bound.
    pub fn constant(&self, c: f64) -> Cv<R> {
        let v = R::of(c);
        let e = (c - v.wide()).abs();
        if !v.wide().is_finite() {
            return self.unknown(v);
        }
        if e == 0.0 {
            return Cv::exact(v);
        }
        // `tiny` covers a bound that rounds below its value in R (or to 0).
        Cv {
            v,
            e: R::of(e * self.acc.grow).add(self.tiny),
        }
    }
}

/// The constant that bounds the device's lattice-to-R^d map against the CPU's: for a vertex
/// u, `|x_device_r - x_cpu_r| <= s_r * lattice_factor` with `s_r = sum_c |A_rc u_c| + |b_r|`
/// (as the device computes it). It covers the device's dot product (d + 1 roundings), the
/// CPU's (its dense product, or the sparse Coxeter and Freudenthal maps, at most d + 4
/// roundings), and in f32 the rounding of A and b to f32.
pub fn lattice_factor(acc: &Accuracy, d: usize) -> f64 {
    let rep = if acc.unit > acc.cpu { acc.unit } else { 0.0 };
    let d = d as f64;
    ((d + 2.0) * acc.unit + (d + 6.0) * acc.cpu + rep) * 1.01
}

/// The CPU twin of the certified shader at one point: `x` the device's coordinates and
/// `ex` their bounds; one [`Cv`] per output into `out`.
pub fn certified_eval<R: DeviceReal>(
    prog: &Program,
    rules: &Rules<R>,
    x: &[Cv<R>],
    out: &mut [Cv<R>],
    regs: &mut Vec<Cv<R>>,
) {
    regs.clear();
    for node in prog.nodes() {
        let at = |i: u32| regs[i as usize];
        let c = match *node {
            Node::Var(i) => x[i],
            Node::Const(c) => rules.constant(c),
            Node::Un(op, a) => rules.un(op, at(a)),
            Node::Bin(op, a, b) => rules.bin(op, at(a), at(b)),
            Node::PowI(a, n) => rules.powi(at(a), n),
        };
        regs.push(c);
    }
    for (o, &n) in out.iter_mut().zip(prog.output_nodes()) {
        *o = regs[n as usize];
    }
}

/// The device's coordinates of the lattice vertex `u` under x = A u + b (A row-major, d x d),
/// summed as the shader sums them, with their bounds against the CPU's coordinates.
pub fn lattice_point<R: DeviceReal>(
    rules: &Rules<R>,
    a: &[f64],
    b: &[f64],
    u: &[i32],
    out: &mut [Cv<R>],
) {
    let d = u.len();
    let factor = R::of(lattice_factor(&rules.acc, d));
    for (r, o) in out.iter_mut().enumerate() {
        let row = &a[r * d..(r + 1) * d];
        let ur = R::of(u[0] as f64);
        let mut acc = R::of(row[0]).mul(ur);
        let mut size = acc.abs();
        for c in 1..d {
            let t = R::of(row[c]).mul(R::of(u[c] as f64));
            acc = acc.add(t);
            size = size.add(t.abs());
        }
        let br = R::of(b[r]);
        let v = acc.add(br);
        size = size.add(br.abs());
        *o = Cv {
            v,
            e: size.mul(factor).add(rules.tiny),
        };
    }
}
