// Certified values: each function returns vec2(v, e), the device's value and a bound such
// that the exact value and the CPU's f64 value both lie within e of v. The CPU twin, rule for
// rule and in the same order, is `isomesh::expr::certified::Rules`; its module documentation
// states the rules' contract. The host prepends `alias real`, the constants CB_* (written from
// `Accuracy`) and the device primitives cb_dev_exp, cb_dev_ln, cb_dev_sin, cb_dev_cos and
// cb_dev_atan2. `cpu` is 1 where the CPU performs the operation itself, 0 inside a composite.

alias Cv = vec2<real>;

fn cb_exact(v: real) -> Cv {
    return Cv(v, real(0.0));
}

fn cb_unknown(v: real) -> Cv {
    return Cv(v, CB_BIG);
}

fn cb_done(v: real, e: real) -> Cv {
    let g = e * CB_GROW + CB_TINY;
    // NaN fails both comparisons.
    if (g < CB_BIG && abs(v) < CB_BIG) {
        return Cv(v, g);
    }
    return cb_unknown(v);
}

fn cb_known(a: Cv) -> bool {
    return abs(a.x) < CB_BIG && a.y < CB_BIG;
}

fn cb_cpu_unit(cpu: bool) -> real {
    return select(real(0.0), CB_CPU, cpu);
}

fn cb_known2(a: Cv, b: Cv) -> bool {
    return cb_known(a) && cb_known(b);
}

fn cb_sum(a: Cv, b: Cv, v: real, cpu: bool) -> Cv {
    if (!cb_known2(a, b)) {
        return cb_unknown(v);
    }
    let eab = a.y + b.y;
    let size = abs(a.x) + abs(b.x) + eab;
    return cb_done(v, eab + (CB_UNIT + cb_cpu_unit(cpu)) * size);
}

fn cb_add(a: Cv, b: Cv, cpu: bool) -> Cv {
    return cb_sum(a, b, a.x + b.x, cpu);
}

fn cb_sub(a: Cv, b: Cv, cpu: bool) -> Cv {
    return cb_sum(a, b, a.x - b.x, cpu);
}

fn cb_mul(a: Cv, b: Cv, cpu: bool) -> Cv {
    if (!cb_known2(a, b)) {
        return cb_unknown(a.x * b.x);
    }
    let ae = a.y + CB_TINY;
    let be = b.y + CB_TINY;
    let ma = abs(a.x) + ae;
    let mb = abs(b.x) + be;
    let prop = abs(a.x) * be + abs(b.x) * ae + ae * be;
    return cb_done(a.x * b.x, prop + (CB_UNIT + cb_cpu_unit(cpu)) * (ma * mb));
}

fn cb_div(a: Cv, b: Cv, cpu: bool) -> Cv {
    let q = a.x / b.x;
    if (!cb_known2(a, b)) {
        return cb_unknown(q);
    }
    let ae = a.y + CB_TINY;
    let be = b.y + CB_TINY;
    let bb = abs(b.x);
    let den = bb - be;
    if (!(den >= CB_DIV_MIN) || !(bb <= CB_DIV_MAX)) {
        return cb_unknown(q);
    }
    let qa = abs(q) * (real(1.0) + real(2.0) * CB_DIV);
    let prop = qa * (be / den) + ae / den;
    let round = CB_DIV + cb_cpu_unit(cpu);
    return cb_done(q, prop + round * (abs(a.x) + ae) / den);
}

fn cb_sqrt(a: Cv, cpu: bool) -> Cv {
    let y = sqrt(a.x);
    if (!cb_known(a) || !(a.x - a.y >= CB_SQRT_MIN) || !(a.x <= CB_SQRT_MAX)) {
        return cb_unknown(y);
    }
    let by_slope = a.y / (y * (real(1.0) - CB_SQRT));
    var prop = by_slope;
    if (a.y == real(0.0)) {
        prop = real(0.0);
    } else if (a.y >= CB_SQRT_MIN) {
        let by_root = sqrt(a.y) * (real(1.0) + CB_SQRT);
        if (!(by_slope < by_root)) {
            prop = by_root;
        }
    }
    return cb_done(y, prop + (CB_SQRT + cb_cpu_unit(cpu)) * (abs(y) + prop));
}

fn cb_cpu_fn(r: Cv) -> Cv {
    if (!cb_known(r)) {
        return r;
    }
    return cb_done(r.x, r.y + CB_CPU_FN * (abs(r.x) + r.y));
}

fn cb_exp_claim(x: real) -> real {
    return CB_EXP0 + CB_EXP1 * abs(x);
}

fn cb_exp_raw(a: Cv) -> Cv {
    let y = cb_dev_exp(a.x);
    let top = a.x + a.y;
    if (!cb_known(a) || !(abs(a.x) <= CB_EXP_MAX) || !(top <= CB_EXP_MAX) || !(a.x - a.y >= -CB_EXP_MAX)) {
        return cb_unknown(y);
    }
    let prop = cb_dev_exp(top) * (real(1.0) + cb_exp_claim(top)) * a.y;
    return cb_done(y, prop + cb_exp_claim(a.x) * abs(y));
}

fn cb_ln_raw(a: Cv) -> Cv {
    let y = cb_dev_ln(a.x);
    let lo = a.x - a.y;
    if (!cb_known(a) || !(lo >= CB_DIV_MIN) || !(a.x >= CB_LN_MIN) || !(a.x <= CB_LN_MAX)) {
        return cb_unknown(y);
    }
    return cb_done(y, a.y / lo + (CB_LN_REL * abs(y) + CB_LN_ABS));
}

fn cb_trig_raw(a: Cv, cos: bool) -> Cv {
    let y = select(cb_dev_sin(a.x), cb_dev_cos(a.x), cos);
    if (!cb_known(a) || !(abs(a.x) <= CB_TRIG_MAX)) {
        return cb_unknown(y);
    }
    let own = CB_TRIG_ABS + CB_TRIG_REL * abs(a.x);
    let prop = select(real(2.0), a.y, a.y < real(2.0));
    return cb_done(y, prop + own);
}

fn cb_atan2_raw(y: Cv, x: Cv) -> Cv {
    let t = cb_dev_atan2(y.x, x.x);
    let r = max(abs(x.x), abs(y.x));
    let delta = y.y + x.y;
    // Near the cut the sign of y decides; one the built-in may flush is not known.
    let cut = x.x - x.y < real(0.0) && !(abs(y.x) > y.y + CB_BUILTIN_FLUSH);
    if (!cb_known2(y, x) || !(delta < r) || cut || !(r >= CB_ATAN_MIN) || !(r <= CB_ATAN_MAX)) {
        return cb_unknown(t);
    }
    let prop = real(1.5707963267948966) * delta / r;
    return cb_done(t, prop + (CB_ATAN_REL * abs(t) + CB_ATAN_ABS));
}

fn cb_neg(a: Cv) -> Cv {
    return Cv(-a.x, a.y);
}

fn cb_abs(a: Cv) -> Cv {
    return Cv(abs(a.x), a.y);
}

fn cb_sign(a: Cv) -> Cv {
    if (!cb_known(a)) {
        return cb_unknown(real(0.0));
    }
    if (a.x - a.y > real(0.0)) {
        return cb_exact(real(1.0));
    }
    if (a.x + a.y < real(0.0)) {
        return cb_exact(real(-1.0));
    }
    if (a.x == real(0.0) && a.y == real(0.0)) {
        return cb_exact(real(0.0));
    }
    return Cv(real(0.0), real(1.0));
}

fn cb_exp(a: Cv) -> Cv {
    return cb_cpu_fn(cb_exp_raw(a));
}

fn cb_ln(a: Cv) -> Cv {
    return cb_cpu_fn(cb_ln_raw(a));
}

fn cb_sin(a: Cv) -> Cv {
    return cb_cpu_fn(cb_trig_raw(a, false));
}

fn cb_cos(a: Cv) -> Cv {
    return cb_cpu_fn(cb_trig_raw(a, true));
}

fn cb_tan(a: Cv) -> Cv {
    return cb_cpu_fn(cb_div(cb_trig_raw(a, false), cb_trig_raw(a, true), false));
}

fn cb_atan(a: Cv) -> Cv {
    return cb_cpu_fn(cb_atan2_raw(a, cb_exact(real(1.0))));
}

fn cb_root_one_minus_square(a: Cv) -> Cv {
    return cb_sqrt(cb_sub(cb_exact(real(1.0)), cb_mul(a, a, false), false), false);
}

fn cb_asin(a: Cv) -> Cv {
    return cb_cpu_fn(cb_atan2_raw(a, cb_root_one_minus_square(a)));
}

fn cb_acos(a: Cv) -> Cv {
    return cb_cpu_fn(cb_atan2_raw(cb_root_one_minus_square(a), a));
}

fn cb_sinh(a: Cv) -> Cv {
    let ex = cb_exp_raw(a);
    let inv = cb_div(cb_exact(real(1.0)), ex, false);
    return cb_cpu_fn(cb_mul(cb_sub(ex, inv, false), cb_exact(real(0.5)), false));
}

fn cb_cosh(a: Cv) -> Cv {
    let ex = cb_exp_raw(cb_abs(a));
    let inv = cb_div(cb_exact(real(1.0)), ex, false);
    return cb_cpu_fn(cb_mul(cb_add(ex, inv, false), cb_exact(real(0.5)), false));
}

fn cb_tanh(a: Cv) -> Cv {
    let t = cb_exp_raw(cb_mul(cb_abs(a), cb_exact(real(-2.0)), false));
    let one = cb_exact(real(1.0));
    let q = cb_div(cb_sub(one, t, false), cb_add(one, t, false), false);
    return cb_cpu_fn(cb_mul(cb_sign(a), q, false));
}

fn cb_min(a: Cv, b: Cv) -> Cv {
    if (!cb_known2(a, b)) {
        return cb_unknown(a.x);
    }
    return cb_done(select(b.x, a.x, a.x < b.x), max(a.y, b.y));
}

fn cb_max(a: Cv, b: Cv) -> Cv {
    if (!cb_known2(a, b)) {
        return cb_unknown(a.x);
    }
    return cb_done(select(a.x, b.x, a.x < b.x), max(a.y, b.y));
}

fn cb_pow(a: Cv, b: Cv) -> Cv {
    return cb_cpu_fn(cb_exp_raw(cb_mul(b, cb_ln_raw(a), false)));
}

fn cb_atan2(a: Cv, b: Cv) -> Cv {
    return cb_cpu_fn(cb_atan2_raw(a, b));
}
