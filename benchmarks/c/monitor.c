/* The monitor model's kernel in plain C: a line-by-line port of the numba kernel
 * (ema_bench/physics/integrator.py, ema_bench/monitor.py, ema_bench/physics/averaged_drive.py,
 * ema_bench/physics/mechanics.py, ema_bench/physics/ace.py, ema_bench/physics/effect_terms.py,
 * ema_bench/physics/load.py, ema_bench/physics/trig.py), the same floating-point operations in
 * the same order.
 *
 * It exists only to measure how far the numba kernel is from C (`ema-bench bench`) and to check
 * that the two agree (tests/test_kernel.py); it is not part of the installed package.
 * Positions in the parameter and effect arrays come from Python (IDX_* below), so nothing here
 * depends on the order of the parameter set.
 *
 * Build: cc -O3 -march=native -ffp-contract=off -fno-trapping-math -fno-math-errno -fPIC -shared
 *        monitor.c -o libmonitor.so -lm
 * (-ffp-contract=off: no fused multiply-add, which numba does not use either; the last two let
 * GCC vectorise floor() in the lanes and change no result).
 */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

/* order of the index table passed in from Python (ema_bench.c_kernel.index_table) */
enum {
    IDX_VDC, IDX_R, IDX_L, IDX_KE, IDX_PP, IDX_HYST, IDX_JM, IDX_JU, IDX_TAU, IDX_KS, IDX_CS,
    IDX_CM, IDX_CU, IDX_KAERO, IDX_THSTOP, IDX_KSTOP, IDX_CSTOP, IDX_FDYN, IDX_WSTICK, IDX_KGP,
    IDX_WMAX, IDX_KPV, IDX_KIV, IDX_TMAX, IDX_DTC, IDX_KTF, IDX_LOCATE, IDX_LIBM,
    IDX_E_ECC, IDX_E_OFFSET, IDX_E_VISC, IDX_E_AERO, IDX_E_DELAY, IDX_E_IGAIN, IDX_E_RRISE,
    IDX_E_COG, IDX_E_VSAG, IDX_E_GEAR, IDX_E_QDAMP, IDX_E_HFRIC, IDX_E_TERM0, IDX_E_RESOLVER2, IDX_N
};
#define MAX_DELAY_SAMPLES 64
#define HINGE_FRICTION_SPEED 0.01
/* ema_bench.terms: the dictionary's size, its current-loop and sensor slots, its sign terms'
   smoothing speeds and current, the back-EMF harmonic's order */
#define N_TERMS 31
#define T_CURRENT0 20
#define T_SENSOR0 24
#define SIGN_SPEED_MOTOR 3.0
#define STRIBECK_SPEED 30.0
#define SIGN_SPEED_SURFACE 0.01
#define SIGN_CURRENT 0.5
#define EMF_ORDER 6

static const double SIXTH = M_PI / 6.0;

static inline int64_t pymod(int64_t a, int64_t b) { int64_t r = a % b; return r < 0 ? r + b : r; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

/* ---- trig.py: sine and cosine by range reduction and polynomials (bit-identical to numba) -- */
static const double P1 = 1.57079632673412561417e+00, P2 = 6.07710050630396597660e-11,
                    P3 = 2.02226624871116645580e-21, TWO_OVER_PI = 6.36619772367581382433e-01;
static const double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                    S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                    S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
static const double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                    C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                    C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;

static inline void trig_reduce(double x, double *q_, double *s_, double *c_) {
    double n = floor(x * TWO_OVER_PI + 0.5);
    double r = ((x - n * P1) - n * P2) - n * P3;
    double q = n - 4.0 * floor(n * 0.25);
    double z = r * r;
    double s = r + (z * r) * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))));
    double hz = 0.5 * z, w = 1.0 - hz;
    double c = w + (((1.0 - w) - hz)
                    + (z * z) * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6))))));
    *q_ = q; *s_ = s; *c_ = c;
}

static inline void poly_sincos(double x, double *sin_, double *cos_) {
    double q, s, c;
    trig_reduce(x, &q, &s, &c);
    bool swap = (q == 1.0) | (q == 3.0);
    double a = swap ? c : s, b = swap ? s : c;
    *sin_ = q >= 2.0 ? -a : a;
    *cos_ = (q == 1.0) | (q == 2.0) ? -b : b;
}

static inline double poly_sin(double x) {
    double s, c;
    poly_sincos(x, &s, &c);
    return s;
}

/* ---- ace.py ------------------------------------------------------------------------------ */
typedef struct { double k_pos, w_max, kpv, kiv, t_max, dtc, amps_per_nm; } Ctrl;

static Ctrl ace_consts(const double *p, const int64_t *ix, double gprop) {
    Ctrl c = {p[ix[IDX_KGP]] * gprop / p[ix[IDX_TAU]], p[ix[IDX_WMAX]], p[ix[IDX_KPV]],
              p[ix[IDX_KIV]], p[ix[IDX_TMAX]], p[ix[IDX_DTC]], 1.0 / (2.0 * p[ix[IDX_KE]])};
    return c;
}

static inline double ace_update(double theta_cmd, double theta_u_meas, double w_m_meas,
                                double *integ, const Ctrl *cc) {
    double w_ref = cc->k_pos * (theta_cmd - theta_u_meas);
    if (w_ref > cc->w_max) w_ref = cc->w_max;
    else if (w_ref < -cc->w_max) w_ref = -cc->w_max;
    double ew = w_ref - w_m_meas;
    double t_unsat = cc->kpv * ew + cc->kiv * *integ;
    double t_ref = t_unsat;
    if (t_ref > cc->t_max) t_ref = cc->t_max;
    else if (t_ref < -cc->t_max) t_ref = -cc->t_max;
    if (t_ref == t_unsat || (t_unsat > cc->t_max && ew < 0.0) || (t_unsat < -cc->t_max && ew > 0.0))
        *integ += ew * cc->dtc;
    return t_ref * cc->amps_per_nm;
}

static inline double stored(const double *buf, int64_t k) {
    return k < 0 ? buf[0] : buf[pymod(k, MAX_DELAY_SAMPLES + 1)];
}

static inline double delayed_feedback(double *buf, int64_t k_ctrl, double value, double delay) {
    buf[pymod(k_ctrl, MAX_DELAY_SAMPLES + 1)] = value;
    if (delay <= 0.0) return value;
    int64_t d0 = (int64_t)floor(delay);
    double frac = delay - d0;
    return (1.0 - frac) * stored(buf, k_ctrl - d0) + frac * stored(buf, k_ctrl - d0 - 1);
}

/* ---- averaged_drive.py ---------------------------------------------------------------------- */
typedef struct {
    double kt_a, kt_n, r_a, r_n, il_a, il_n, ltr_a, ltr_n, na, ke, pp, zeta, v_dc, ktf, half_band,
        h, sector_width, th_0;
    bool locate, libm;
} Drive;

static Drive drive_consts(const double *p, const int64_t *ix, double na, double zeta,
                          double r_scale, double v_dc, double h) {
    double ke = p[ix[IDX_KE]], el = p[ix[IDX_L]], r = p[ix[IDX_R]] * r_scale;
    Drive d = {ke * (na + 1.0), 2.0 * ke, r * (na + 1.0), 2.0 * r,
               1.0 / (el * (na * na + 1.0)), 1.0 / (2.0 * el),
               el * (na * na + 1.0) / v_dc, 2.0 * el / v_dc, na, ke, p[ix[IDX_PP]], zeta,
               v_dc, p[ix[IDX_KTF]], 0.5 * p[ix[IDX_HYST]], h, 2.0 * SIXTH / p[ix[IDX_PP]],
               SIXTH / p[ix[IDX_PP]], p[ix[IDX_LOCATE]] != 0.0, p[ix[IDX_LIBM]] != 0.0};
    return d;
}

static const double COS_120 = -0.5, SIN_120 = 0.86602540378443864676;  /* sqrt(3) / 2 */
/* phases b's and c's shifts (model version 2: libm's cos(th_m - phi)) */
static const double PHI_B = 2.0 * M_PI / 3.0, PHI_C = 4.0 * M_PI / 3.0;

static inline double kt_eccentric(double sec, double th_m, double ke, double na, double zeta) {
    double s, c;
    poly_sincos(th_m, &s, &c);
    double cx = sec < 2 ? 1.0 : COS_120;
    double sx = sec < 2 ? 0.0 : (sec < 4 ? SIN_120 : -SIN_120);
    double nx = sec < 2 ? na : 1.0;
    bool y_is_a = (sec == 3) | (sec == 4);
    double cy = y_is_a ? 1.0 : COS_120;
    double sy = y_is_a ? 0.0 : ((sec == 0) | (sec == 5) ? SIN_120 : -SIN_120);
    double ny = y_is_a ? na : 1.0;
    return ke * (nx * (1.0 + zeta * (c * cx + s * sx)) + ny * (1.0 + zeta * (c * cy + s * sy)));
}

/* model version 2 (libm_trig): libm's cosine of each conducting phase */
static inline double kt_eccentric_libm(double sec, double th_m, double ke, double na,
                                       double zeta) {
    double phx = sec < 2 ? 0.0 : (sec < 4 ? PHI_B : PHI_C);
    double nx = sec < 2 ? na : 1.0;
    bool y_is_a = (sec == 3) | (sec == 4);
    double phy = y_is_a ? 0.0 : ((sec == 0) | (sec == 5) ? PHI_B : PHI_C);
    double ny = y_is_a ? na : 1.0;
    return ke * (nx * (1.0 + zeta * cos(th_m - phx)) + ny * (1.0 + zeta * cos(th_m - phy)));
}

static inline double kt_eccentric_of(double sec, double th_m, const Drive *dc) {
    if (dc->libm) return kt_eccentric_libm(sec, th_m, dc->ke, dc->na, dc->zeta);
    return kt_eccentric(sec, th_m, dc->ke, dc->na, dc->zeta);
}

static inline double kt_at(int64_t sec, double th_m, const Drive *dc) {
    if (dc->zeta == 0.0) return pymod(sec, 3) == 2 ? dc->kt_n : dc->kt_a;
    return kt_eccentric_of((double)sec, th_m, dc);
}

static inline double ramp_integral(double lo, double hi, double t_tr) {
    return (0.5 * hi * hi - hi * hi * hi / (3.0 * t_tr)) - (0.5 * lo * lo - lo * lo * lo / (3.0 * t_tr));
}

static inline int64_t sector_index(double th_m, double pole_pairs) {
    return (int64_t)floor((pole_pairs * th_m - SIXTH) / (2.0 * SIXTH));
}

typedef struct { double cur; int64_t m; double tr_t0, tr_len, kt_from, kt_to, tr_cr; } DState;
typedef struct { double t_mean, t_start, t_end, t_rip, i_eq; } DOut;

static inline void ramp(double cur, double i_ref, double back, double il, double v_dc, double h,
                        double *cur1_, double *f_, double *i_mean_, double *i_eq_) {
    double up = h * (v_dc - back) * il;
    double dn = h * (-v_dc - back) * il;
    double cur1 = i_ref;
    if (cur1 > cur + up) cur1 = cur + up;
    else if (cur1 < cur + dn) cur1 = cur + dn;
    double d = cur1 - cur, f;
    if (up > 0.0 && dn < 0.0) f = dmax(d * (1.0 / up), d * (1.0 / dn));
    else if (d > 0.0) f = d / up;
    else if (d < 0.0) f = d / dn;
    else f = 0.0;
    double i_mean = cur1 - (0.5 * d) * f, ramp_abs;
    if (cur * cur1 >= 0.0) ramp_abs = 0.5 * fabs(cur + cur1);
    else ramp_abs = 0.5 * (cur * cur + cur1 * cur1) / fabs(d);
    *cur1_ = cur1; *f_ = f; *i_mean_ = i_mean; *i_eq_ = f * ramp_abs + (1.0 - f) * fabs(cur1);
}

/* the commutation transfer of a crossing out of sector sec (0..5), as _transfer */
static inline void transfer(int64_t sec, bool up, double th_b, double i_tr, double w_m,
                            const Drive *dc, double *kt_from, double *kt_to, double *tr_len,
                            double *tr_cr) {
    int64_t k3 = pymod(sec, 3), sec_to;
    double ltr, ny;
    if (up) {
        ltr = k3 == 0 ? dc->ltr_n : dc->ltr_a; ny = k3 == 1 ? dc->na : 1.0;
        sec_to = pymod(sec + 1, 6);
    } else {
        ltr = k3 == 1 ? dc->ltr_n : dc->ltr_a; ny = k3 == 0 ? dc->na : 1.0;
        sec_to = pymod(sec + 5, 6);
    }
    *kt_from = kt_at(sec, th_b, dc);
    *kt_to = kt_at(sec_to, th_b, dc);
    *tr_len = dmax(i_tr * ltr, 1e-12);
    *tr_cr = ny * dc->ke * dc->pp * fabs(w_m) / SIXTH * i_tr;
}

/* kt_hint: NULL, or the torque constants of sector s->m at th_m and mid-step that the caller
   already computed (the lanes), used while the step stays in that sector */
static void drive_step_general(DState *s, double i_ref, double th_m, double w_m, const Drive *dc,
                               const double *kt_hint, double v_x, DOut *o) {
    double h = dc->h, pp = dc->pp;
    int64_t m = s->m, m_in = s->m;
    double tr_t0 = s->tr_t0, tr_len = s->tr_len, kt_from = s->kt_from, kt_to = s->kt_to,
           tr_cr = s->tr_cr;
    double th_lo = dc->th_0 + dc->sector_width * m, th_hi = th_lo + dc->sector_width;
    if (th_m >= th_hi || th_m < th_lo) {
        int64_t m0 = m;
        m = sector_index(th_m, pp);
        th_lo = dc->th_0 + dc->sector_width * m;
        th_hi = th_lo + dc->sector_width;
        if (dc->locate && m != m0) {   /* model version 4: the missed crossing, located */
            bool up = m > m0;
            double th_b = up ? th_lo : th_hi;
            tr_t0 = w_m != 0.0 ? (th_b - th_m) / w_m : 0.0;
            tr_t0 = tr_t0 > -h ? tr_t0 : -h;
            tr_t0 = tr_t0 < 0.0 ? tr_t0 : 0.0;
            transfer(pymod(up ? m - 1 : m + 1, 6), up, th_b, fabs(s->cur), w_m, dc, &kt_from,
                     &kt_to, &tr_len, &tr_cr);
        }
    }
    int64_t sec = pymod(m, 6);
    bool with_a = pymod(sec, 3) != 2;
    double kt0 = kt_hint && m == m_in ? kt_hint[0] : kt_at(sec, th_m, dc);
    double r_pair = with_a ? dc->r_a : dc->r_n, il = with_a ? dc->il_a : dc->il_n;
    double cur = s->cur, cur1, f, i_mean, i_eq;
    ramp(cur, i_ref, kt0 * w_m + r_pair * cur - v_x, il, dc->v_dc, h, &cur1, &f, &i_mean,
         &i_eq);
    double th_end = th_m + h * w_m;
    if (th_end >= th_hi || th_end < th_lo) {
        bool up = th_end >= th_hi;
        double g = ((up ? th_hi : th_lo) - th_m) / (h * w_m);
        double th_b = up ? th_hi : th_lo;
        double i_tr = f > 0.0 ? fabs(cur + (cur1 - cur) * (g < f ? g : f) / f) : fabs(cur1);
        transfer(sec, up, th_b, i_tr, w_m, dc, &kt_from, &kt_to, &tr_len, &tr_cr);
        m += up ? 1 : -1;
        sec = pymod(m, 6);
        tr_t0 = g * h;
    }
    double deficit = 0.0, kt_mean, kt_start, kt_end;
    if (tr_t0 < h && tr_t0 + tr_len > 0.0) {
        double a = tr_t0 > 0.0 ? tr_t0 : 0.0;
        double b = tr_t0 + tr_len < h ? tr_t0 + tr_len : h;
        double fa = (a - tr_t0) / tr_len, fb = (b - tr_t0) / tr_len;
        double dk = kt_to - kt_from;
        kt_mean = (kt_from * a + (b - a) * (kt_from + dk * 0.5 * (fa + fb)) + kt_to * (h - b)) / h;
        kt_start = tr_t0 <= 0.0 ? kt_from + dk * fa : kt_from;
        kt_end = b < h ? kt_from + dk * fb : kt_to;
        deficit = tr_cr * ramp_integral(a - tr_t0, b - tr_t0, tr_len) / h;
    } else {
        kt_mean = dc->zeta == 0.0 ? kt0
                  : kt_hint && m == m_in ? kt_hint[1] : kt_at(sec, th_m + 0.5 * h * w_m, dc);
        kt_start = kt0;
        kt_end = kt_mean;
    }
    double ktf = dc->ktf;
    double t_mean = (ktf * kt_mean) * i_mean;
    if (deficit != 0.0) t_mean -= ktf * (i_mean > 0.0 ? deficit : -deficit);
    s->cur = cur1; s->m = m; s->tr_t0 = tr_t0 - h; s->tr_len = tr_len; s->kt_from = kt_from;
    s->kt_to = kt_to; s->tr_cr = tr_cr;
    o->t_mean = t_mean; o->t_start = ktf * kt_start * cur; o->t_end = ktf * kt_end * cur1;
    o->t_rip = ktf * fabs(kt_end) * dc->half_band; o->i_eq = i_eq;
}

static inline void drive_step(DState *s, double i_ref, double th_m, double w_m, const Drive *dc,
                              double v_x, DOut *o) {
    double h = dc->h;
    double th_lo = dc->th_0 + dc->sector_width * s->m, th_hi = th_lo + dc->sector_width;
    double th_end = th_m + h * w_m;
    if (s->tr_t0 + s->tr_len <= 0.0 && th_lo <= th_m && th_m < th_hi && th_lo <= th_end &&
        th_end < th_hi) {
        int64_t sec = pymod(s->m, 6);
        double kt, r_pair, il;
        if (sec == 2 || sec == 5) { kt = dc->kt_n; r_pair = dc->r_n; il = dc->il_n; }
        else { kt = dc->kt_a; r_pair = dc->r_a; il = dc->il_a; }
        double kt_mid = kt;
        if (dc->zeta != 0.0) {
            kt = kt_eccentric_of((double)sec, th_m, dc);
            kt_mid = kt_eccentric_of((double)sec, th_m + 0.5 * h * w_m, dc);
        }
        double cur = s->cur, cur1, f, i_mean, i_eq;
        ramp(cur, i_ref, kt * w_m + r_pair * cur - v_x, il, dc->v_dc, h, &cur1, &f, &i_mean,
             &i_eq);
        double kf = dc->ktf * kt, km = dc->ktf * kt_mid;
        s->cur = cur1; s->tr_t0 = s->tr_t0 - h;
        o->t_mean = km * i_mean; o->t_start = kf * cur; o->t_end = km * cur1;
        o->t_rip = fabs(km) * dc->half_band; o->i_eq = i_eq;
        return;
    }
    drive_step_general(s, i_ref, th_m, w_m, dc, NULL, v_x, o);
}

/* ---- mechanics.py --------------------------------------------------------------------------- */
typedef struct {
    double tau, jm, ju, k, c, cm, ka, cu, fst, fdyn, half, w_stick, th_stop, k_stop, c_stop, h,
        b_c, g_h, i11, i12, i22, i_u_stuck, i_m_free, i_u_free, i11h, i12h, i_m_free_h;
} Mech;

static Mech mech_consts(const double *p, const int64_t *ix, double fst, double blk,
                        double c_m_extra, double k_aero_extra, double ks_scale, double h) {
    double tau = p[ix[IDX_TAU]], jm = p[ix[IDX_JM]], ju = p[ix[IDX_JU]];
    double k = p[ix[IDX_KS]] * ks_scale, c = p[ix[IDX_CS]];
    double cm = p[ix[IDX_CM]] + c_m_extra, ka = p[ix[IDX_KAERO]] + k_aero_extra, cu = p[ix[IDX_CU]];
    double b_c = 0.25 * k * h + 0.5 * c, g_h = 0.25 * ka * h + 0.5 * cu;
    double a11 = jm + 0.5 * h * cm + h * tau * tau * b_c;
    double a12 = -h * tau * b_c;
    double a22 = ju + h * b_c + h * g_h;
    double det = a11 * a22 - a12 * a12;
    double i11 = a22 / det, i12 = -a12 / det, i_m_free = 1.0 / (jm + 0.5 * h * cm);
    Mech mc = {tau, jm, ju, k, c, cm, ka, cu, fst, p[ix[IDX_FDYN]] * fst, 0.5 * blk,
               p[ix[IDX_WSTICK]], p[ix[IDX_THSTOP]], p[ix[IDX_KSTOP]], p[ix[IDX_CSTOP]], h, b_c,
               g_h, i11, i12, a11 / det, 1.0 / a22, i_m_free, 1.0 / (ju + h * g_h), i11 * h,
               i12 * h, i_m_free * h};
    return mc;
}

static inline int contact_side(double delta, double half) {
    return delta > half ? 1 : (delta < -half ? -1 : 0);
}

static inline double side_mean(double a, double lim, double k, double c, double d0, double dd,
                               double h) {
    double t1, t2;
    if (dd == 0.0) {
        if (d0 <= a) return 0.0;
        t1 = 0.0; t2 = h;
    } else {
        double tc = (a - d0) / dd;
        if (dd > 0.0) { t1 = tc > 0.0 ? tc : 0.0; t2 = h; }
        else { t1 = 0.0; t2 = tc < h ? tc : h; }
        if (t2 <= t1) return 0.0;
    }
    double f1 = k * (d0 + dd * t1 - lim) + c * dd;
    double f2 = k * (d0 + dd * t2 - lim) + c * dd;
    return 0.5 * (t2 - t1) * (f1 + f2) / h;
}

static inline double gear_mean(double delta, double d_delta, double half, double k, double c,
                               double h) {
    double lift = c * d_delta / k;
    double t = side_mean(half + (lift < 0.0 ? -lift : 0.0), half, k, c, delta, d_delta, h);
    t -= side_mean(half + (lift > 0.0 ? lift : 0.0), half, k, c, -delta, -d_delta, h);
    return t;
}

static inline void rhs(double th_u, double w_m, double w_u, double t_ext, double sgn,
                       const Mech *mc, double *r1, double *r2) {
    double h = mc->h;
    *r1 = mc->jm * w_m - h * (sgn * mc->fdyn + 0.5 * mc->cm * w_m);
    *r2 = mc->ju * w_u + h * ((-mc->ka * th_u - mc->g_h * w_u) + t_ext);
}

static inline void contact_solve(double delta, double dd, int side, double r1, double r2,
                                 double t_m, bool moving, const Mech *mc, double *wm1,
                                 double *wu1, double *t_g) {
    double h = mc->h, tau = mc->tau;
    double off = side > 0 ? mc->half : -mc->half;
    double a = mc->k * (delta - off) + mc->b_c * dd;
    double b1 = r1 - h * tau * a, b2 = r2 + h * a;
    if (moving) {
        *wm1 = (mc->i11 * b1 + mc->i12 * b2) + mc->i11h * t_m;
        *wu1 = (mc->i12 * b1 + mc->i22 * b2) + mc->i12h * t_m;
    } else {
        *wm1 = 0.0;
        *wu1 = b2 * mc->i_u_stuck;
    }
    *t_g = a + mc->b_c * (tau * *wm1 - *wu1);
}

typedef struct { double th_m, w_m, th_u, w_u, m_th_m, m_w_m, m_th_u; } MOut;

static void mech_step_general(double th_m, double w_m, double th_u, double w_u, double t_m,
                              double tm0, double tm1, double t_rip, double t_ext, const Mech *mc,
                              MOut *o) {
    double h = mc->h, tau = mc->tau;
    double delta = tau * th_m - th_u, dd = tau * w_m - w_u;
    if (th_u > mc->th_stop) {
        double s_stop = -mc->k_stop * (th_u - mc->th_stop) - mc->c_stop * w_u;
        t_ext += s_stop < 0.0 ? s_stop : 0.0;
    } else if (th_u < -mc->th_stop) {
        double s_stop = -mc->k_stop * (th_u + mc->th_stop) - mc->c_stop * w_u;
        t_ext += s_stop > 0.0 ? s_stop : 0.0;
    }
    bool moving = fabs(w_m) >= mc->w_stick;
    double sgn = 0.0;
    if (moving) sgn = w_m > 0.0 ? 1.0 : -1.0;
    double r1, r2, wm1, wu1, t_g;
    rhs(th_u, w_m, w_u, t_ext, sgn, mc, &r1, &r2);
    int side = contact_side(delta, mc->half), side1 = contact_side(delta + h * dd, mc->half);
    if (side != 0 && side1 == side) {
        contact_solve(delta, dd, side, r1, r2, t_m, moving, mc, &wm1, &wu1, &t_g);
        if (t_g * side < 0.0) {
            t_g = 0.0;
            wm1 = moving ? r1 * mc->i_m_free + mc->i_m_free_h * t_m : 0.0;
            wu1 = r2 * mc->i_u_free;
        }
    } else if (side == 0 && side1 != 0) {
        double off = side1 > 0 ? mc->half : -mc->half;
        double t_c = (off - delta) / dd;
        double hr = h - t_c;
        double bf = hr / h * (0.25 * mc->k * hr + 0.5 * mc->c);
        double a = bf * dd;
        double b1 = r1 + h * t_m - h * tau * a, b2 = r2 + h * a;
        double a11 = mc->jm + 0.5 * h * mc->cm + h * tau * tau * bf;
        double a12 = -h * tau * bf;
        double a22 = mc->ju + h * bf + h * mc->g_h;
        if (moving) {
            double det = a11 * a22 - a12 * a12;
            wm1 = (b1 * a22 - a12 * b2) / det;
            wu1 = (a11 * b2 - a12 * b1) / det;
        } else {
            wm1 = 0.0;
            wu1 = b2 / a22;
        }
        t_g = a + bf * (tau * wm1 - wu1);
        if (t_g * side1 < 0.0) {
            t_g = 0.0;
            wm1 = moving ? r1 * mc->i_m_free + mc->i_m_free_h * t_m : 0.0;
            wu1 = r2 * mc->i_u_free;
        }
    } else {
        t_g = (side != 0 || side1 != 0) ? gear_mean(delta, dd, mc->half, mc->k, mc->c, h) : 0.0;
        wm1 = moving ? (r1 - h * tau * t_g) * mc->i_m_free + mc->i_m_free_h * t_m : 0.0;
        wu1 = (r2 + h * t_g) * mc->i_u_free;
    }
    double th_u1 = th_u + 0.5 * h * (w_u + wu1);
    double m_th_u = 0.5 * (th_u + th_u1);
    double load = mc->cm * w_m + tau * t_g;
    double f_break = mc->fst - t_rip;
    if (f_break < mc->fdyn) f_break = mc->fdyn;
    o->th_u = th_u1; o->w_u = wu1; o->m_th_u = m_th_u;
    if (!moving) {
        double d0 = tm0 - load, d1 = tm1 - load;
        if (fabs(d0) <= f_break) {
            if (fabs(d1) <= f_break) {
                o->th_m = th_m; o->w_m = 0.0; o->m_th_m = th_m; o->m_w_m = 0.0;
                return;
            }
            double s = d1 > 0.0 ? 1.0 : -1.0;
            double g = (s * f_break - d0) / (d1 - d0);
            double rest = (1.0 - g) * h;
            double wb = rest * (0.5 * (s * f_break + d1) - s * mc->fdyn) / mc->jm;
            double dth = 0.5 * rest * wb;
            o->th_m = th_m + dth; o->w_m = wb; o->m_th_m = th_m + 0.5 * dth;
            o->m_w_m = 0.5 * rest * wb / h;
            return;
        }
        double t_drive = t_m - load;
        double s = t_drive > 0.0 ? 1.0 : -1.0;
        double wb = h * (t_drive - s * mc->fdyn) / mc->jm;
        o->th_m = th_m + 0.5 * h * wb; o->w_m = wb; o->m_th_m = th_m + 0.25 * h * wb;
        o->m_w_m = 0.5 * wb;
        return;
    }
    if (wm1 * w_m >= 0.0) {
        double th_m1 = th_m + 0.5 * h * (w_m + wm1);
        o->th_m = th_m1; o->w_m = wm1; o->m_th_m = 0.5 * (th_m + th_m1);
        o->m_w_m = 0.5 * (w_m + wm1);
        return;
    }
    double f = w_m / (w_m - wm1);
    double th_stop = th_m + 0.5 * f * h * w_m;
    double t_drive = t_m - tau * t_g;
    if (fabs(t_drive) <= f_break) {
        o->th_m = th_stop; o->w_m = 0.0; o->m_th_m = 0.5 * (th_m + th_stop);
        o->m_w_m = 0.5 * f * w_m;
        return;
    }
    double s = t_drive > 0.0 ? 1.0 : -1.0;
    double rest = (1.0 - f) * h;
    double w2 = rest * (t_drive - s * mc->fdyn) / mc->jm;
    double th_m1 = th_stop + 0.5 * rest * w2;
    o->th_m = th_m1; o->w_m = w2; o->m_th_m = 0.5 * (th_m + th_m1);
    o->m_w_m = 0.5 * (f * w_m + (1.0 - f) * w2);
}

static inline void mech_step(double th_m, double w_m, double th_u, double w_u, double t_m,
                             double tm0, double tm1, double t_rip, double t_ext, const Mech *mc,
                             MOut *o) {
    double h = mc->h, tau = mc->tau;
    double delta = tau * th_m - th_u, dd = tau * w_m - w_u;
    int side = contact_side(delta, mc->half);
    if (fabs(w_m) >= mc->w_stick && fabs(th_u) <= mc->th_stop &&
        contact_side(delta + h * dd, mc->half) == side) {
        double r1, r2, wm1, wu1, t_g;
        rhs(th_u, w_m, w_u, t_ext, w_m > 0.0 ? 1.0 : -1.0, mc, &r1, &r2);
        bool ok;
        if (side != 0) {
            contact_solve(delta, dd, side, r1, r2, t_m, true, mc, &wm1, &wu1, &t_g);
            ok = t_g * side >= 0.0;
        } else {
            wm1 = r1 * mc->i_m_free + mc->i_m_free_h * t_m;
            wu1 = r2 * mc->i_u_free;
            ok = true;
        }
        if (ok && wm1 * w_m >= 0.0) {
            double th_m1 = th_m + 0.5 * h * (w_m + wm1);
            double th_u1 = th_u + 0.5 * h * (w_u + wu1);
            o->th_m = th_m1; o->w_m = wm1; o->th_u = th_u1; o->w_u = wu1;
            o->m_th_m = 0.5 * (th_m + th_m1); o->m_w_m = 0.5 * (w_m + wm1);
            o->m_th_u = 0.5 * (th_u + th_u1);
            return;
        }
    }
    mech_step_general(th_m, w_m, th_u, w_u, t_m, tm0, tm1, t_rip, t_ext, mc, o);
}

/* ---- effects, load, the monitor plant and the integrator skeleton -------------------------- */
static inline double cogging_torque(double amplitude, double th_m, double pole_pairs,
                                    bool libm) {
    if (amplitude == 0.0) return 0.0;
    if (libm) return amplitude * sin(6.0 * pole_pairs * th_m);   /* model version 2 */
    return amplitude * poly_sin(6.0 * pole_pairs * th_m);
}

static inline double hinge_extra(double w_u, double quad, double hfric) {
    double m = 0.0;
    if (quad != 0.0) m -= quad * w_u * fabs(w_u);
    if (hfric != 0.0) m -= hfric * tanh(w_u / HINGE_FRICTION_SPEED);
    return m;
}

/* physics/extra_terms.py: the term dictionary's torques on the motor and the surface */
static inline void extra_torques(double th_m, double w_m, double th_u, double w_u, double i,
                                 double pp, const double *c, double *motor, double *surface) {
    double s1, c1, se, ce, s2, c2;
    poly_sincos(th_m, &s1, &c1);
    poly_sincos(pp * th_m, &se, &ce);
    poly_sincos(2.0 * pp * th_m, &s2, &c2);
    *motor = c[0] * (w_m * w_m) + c[1] * (w_m * fabs(w_m)) + c[2] * tanh(w_m / SIGN_SPEED_MOTOR)
             + c[3] * i + c[4] * (i * i) + c[5] * (i * fabs(i)) + c[6] * s1 + c[7] * c1
             + c[8] * se + c[9] * ce + c[10] * s2 + c[11] * c2
             + c[19] * (exp(-((w_m / STRIBECK_SPEED) * (w_m / STRIBECK_SPEED)))
                        * tanh(w_m / SIGN_SPEED_MOTOR));
    *surface = c[12] * w_u + c[13] * (th_u * th_u) + c[14] * (th_u * w_u) + c[15] * (w_u * w_u)
               + c[16] * (th_u * fabs(th_u)) + c[17] * (w_u * fabs(w_u))
               + c[18] * tanh(w_u / SIGN_SPEED_SURFACE);
}

/* extra_terms.py: the current loop's voltage and the sensors' errors */
static inline bool any_on(const double *c, int lo, int hi) {
    for (int k = lo; k < hi; k++) if (c[k] != 0.0) return true;
    return false;
}

static inline double loop_voltage(double i, double w_m, double th_m, double pp, const double *c) {
    double s6, c6;
    poly_sincos(EMF_ORDER * pp * th_m, &s6, &c6);
    const int k = T_CURRENT0;
    return c[k] * tanh(i / SIGN_CURRENT) + c[k + 1] * (i * fabs(i)) + c[k + 2] * (w_m * s6)
           + c[k + 3] * (w_m * c6);
}

static inline void angle_error(double th_m, const double *c, double *err, double *slope) {
    double s1, c1, s2, c2;
    poly_sincos(th_m, &s1, &c1);
    poly_sincos(2.0 * th_m, &s2, &c2);
    const int k = T_SENSOR0;
    *err = c[k] * s1 + c[k + 1] * c1 + c[k + 2] * s2 + c[k + 3] * c2;
    *slope = c[k] * c1 - c[k + 1] * s1 + 2.0 * (c[k + 2] * c2 - c[k + 3] * s2);
}

static inline double position_error(double th_u, const double *c) {
    const int k = T_SENSOR0 + 4;
    return c[k] * (th_u * th_u) + c[k + 1] * (th_u * fabs(th_u));
}

static inline double current_error(double i, const double *c) {
    return c[T_SENSOR0 + 6] * (i * fabs(i));
}

/* one candidate, one test (integrator.integrate with the monitor plant) */
static bool integrate(const double *p, const int64_t *ix, const double *x, const double *e,
                      const double *cmd, int64_t n_out, int64_t ticks_out, int64_t steps_tick,
                      double dt, double *out) {
    /* plant_terms, monitor_consts */
    double zeta = e[ix[IDX_E_ECC]], v_dc = p[ix[IDX_VDC]] * (1.0 - e[ix[IDX_E_VSAG]]);
    double r_scale = 1.0 + e[ix[IDX_E_RRISE]], ks_scale = 1.0 - e[ix[IDX_E_GEAR]];
    double c_visc = e[ix[IDX_E_VISC]], k_aero = e[ix[IDX_E_AERO]], cog = e[ix[IDX_E_COG]];
    double quad = e[ix[IDX_E_QDAMP]], hfric = e[ix[IDX_E_HFRIC]];
    const double *tc = e + ix[IDX_E_TERM0];   /* term_consts */
    double inv_kt = 1.0 / (2.0 * p[ix[IDX_KE]]);
    bool on = any_on(tc, 0, T_CURRENT0), v_on = any_on(tc, T_CURRENT0, T_SENSOR0);
    /* sensor_consts: the outside-library resolver harmonic adds to the sin(2 th_m) slot */
    double sc[N_TERMS];
    memcpy(sc, tc, sizeof sc);
    sc[T_SENSOR0 + 2] += e[ix[IDX_E_RESOLVER2]];
    bool s_ang = any_on(sc, T_SENSOR0, T_SENSOR0 + 4);
    bool s_pos = any_on(sc, T_SENSOR0 + 4, T_SENSOR0 + 6);
    bool s_cur = any_on(sc, T_SENSOR0 + 6, T_SENSOR0 + 7);
    Drive dc = drive_consts(p, ix, x[0], zeta, r_scale, v_dc, dt);
    Mech mc = mech_consts(p, ix, x[1], x[2], c_visc, k_aero, ks_scale, dt);
    double pp = p[ix[IDX_PP]];
    Ctrl cc = ace_consts(p, ix, x[3]);
    /* sensor_terms */
    double offset = e[ix[IDX_E_OFFSET]], gain = 1.0 + e[ix[IDX_E_IGAIN]];
    double delay = e[ix[IDX_E_DELAY]] / p[ix[IDX_DTC]];
    double buf[MAX_DELAY_SAMPLES + 1];
    DState ps = {0.0, sector_index(0.0, pp), -1.0, 0.0, 0.0, 0.0, 0.0};
    double th_m = 0.0, w_m = 0.0, th_u = 0.0, w_u = 0.0, integ = 0.0;
    int64_t k_ctrl = 0;
    double scale = 1.0 / (ticks_out * steps_tick);
    for (int64_t k = 0; k < n_out; k++) {
        double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
        for (int64_t t = 0; t < ticks_out; t++) {
            double fb = th_u + offset;
            if (s_pos) fb += position_error(th_u, sc);
            if (delay > 0.0) fb = delayed_feedback(buf, k_ctrl, fb, delay);
            double w_fb = w_m;
            if (s_ang) {
                double err, slope;
                angle_error(th_m, sc, &err, &slope);
                w_fb = w_m * (1.0 + slope);
            }
            double i_ref = ace_update(cmd[k_ctrl], fb, w_fb, &integ, &cc);
            if (s_cur) i_ref -= current_error(i_ref, sc);
            k_ctrl += 1;
            for (int64_t s = 0; s < steps_tick; s++) {
                DOut d;
                double v_x = v_on ? loop_voltage(ps.cur, w_m, th_m, pp, tc) : 0.0;
                drive_step(&ps, i_ref, th_m, w_m, &dc, v_x, &d);
                double t_cog = cogging_torque(cog, th_m + 0.5 * dc.h * w_m, pp, dc.libm);
                double t_ext = hinge_extra(w_u, quad, hfric);
                if (on) {
                    double t_m_x, t_u_x;
                    extra_torques(th_m, w_m, th_u, w_u, d.t_mean * inv_kt, pp, tc, &t_m_x, &t_u_x);
                    t_cog += t_m_x;
                    t_ext += t_u_x;
                }
                MOut m;
                mech_step(th_m, w_m, th_u, w_u, d.t_mean + t_cog, d.t_start + t_cog,
                          d.t_end + t_cog, d.t_rip, t_ext, &mc, &m);
                th_m = m.th_m; w_m = m.w_m; th_u = m.th_u; w_u = m.w_u;
                a0 += m.m_th_u; a1 += m.m_th_m; a2 += m.m_w_m; a3 += d.i_eq;
                if (s_ang) {
                    double err, slope;
                    angle_error(m.m_th_m, sc, &err, &slope);
                    a1 += err;
                    a2 += m.m_w_m * slope;
                }
            }
        }
        out[4 * k + 0] = a0 * scale + offset;
        out[4 * k + 1] = a1 * scale;
        out[4 * k + 2] = a2 * scale;
        out[4 * k + 3] = gain * a3 * scale;
        if (s_pos) out[4 * k + 0] += position_error(a0 * scale, sc);
        if (s_cur) out[4 * k + 3] += gain * current_error(a3 * scale, sc);
        if (!(isfinite(a0) && isfinite(a1) && isfinite(a2) && isfinite(a3))) return false;
    }
    return true;
}

/* every candidate, every test: the layout of ema_bench.monitor.simulate_monitor */
int64_t monitor_batch(const double *p, const int64_t *ix, const double *X, const double *E,
                      int64_t n, int64_t n_effects, const double *cmd, const int64_t *cmd_start,
                      const int64_t *n_out, const int64_t *out_start, int64_t n_tests,
                      int64_t total_out, int64_t ticks_out, int64_t steps_tick, double dt,
                      double *out, uint8_t *ok) {
    int64_t failures = 0;
    for (int64_t c = 0; c < n; c++) {
        bool good = true;
        for (int64_t t = 0; t < n_tests; t++)
            good &= integrate(p, ix, X + 4 * c, E + n_effects * c, cmd + cmd_start[t], n_out[t],
                              ticks_out, steps_tick, dt, out + 4 * (total_out * c + out_start[t]));
        ok[c] = good;
        failures += !good;
    }
    return failures;
}

/* ---- monitor_lanes.py: eight candidates in lock-step lanes ----------------------------------
 * The numba lanes kernel (ema_bench/monitor_lanes.py) line by line: the short paths of a step
 * (controller, drive inside one sector, sliding mechanics, cogging, the eccentric torque
 * constants) as loops over the LANES lanes with selects instead of branches, which the compiler
 * vectorises (-O3; `cc -fopt-info-vec-optimized` lists them); a lane whose step leaves a short
 * path runs the general scalar function above for that lane alone.  Bit-identical to the
 * scalar C and to both numba kernels (tests/test_kernel.py); `ema-bench bench` times it as the
 * SIMD limit the numba lanes are measured against.  Effects: those of LANE_EFFECTS only. */
#define LANES 8
#define DBUF 128   /* _DBUF: a power of two above MAX_DELAY_SAMPLES + 2 */

typedef struct {
    /* state */
    double thm[LANES], wm[LANES], thu[LANES], wu[LANES], cur[LANES], trt0[LANES], trlen[LANES],
        ktf[LANES], ktt[LANES], trcr[LANES], integ[LANES], sec[LANES];
    /* the sector's constants */
    double thlo[LANES], kt[LANES], rp[LANES], il[LANES];
    /* per-step values handed between the loops */
    double iref[LANES], tm[LANES], tm0[LANES], tm1[LANES], trip[LANES], ieq[LANES],
        dslow[LANES], mslow[LANES], a0[LANES], a1[LANES], a2[LANES], a3[LANES], fb[LANES],
        kte[LANES], ktm[LANES], tcog[LANES];
    /* fault- and effect-dependent constants */
    double half[LANES], fdyn[LANES], kpos[LANES], off[LANES], gain[LANES], ecc[LANES],
        cog[LANES], zeta[LANES], na[LANES], k[LANES], cm[LANES], ka[LANES], gh[LANES],
        bc[LANES], i11[LANES], i12[LANES], i22[LANES], i11h[LANES], i12h[LANES], imf[LANES],
        imfh[LANES], iuf[LANES];
    int64_t m[LANES];
} Lanes;

static inline void sector_consts(int64_t m, const Drive *dc, double *th_lo, double *kt,
                                 double *rp, double *il) {
    *th_lo = dc->th_0 + dc->sector_width * m;
    int64_t sec = pymod(m, 6);
    bool without_a = sec == 2 || sec == 5;
    *kt = without_a ? dc->kt_n : dc->kt_a;
    *rp = without_a ? dc->r_n : dc->r_a;
    *il = without_a ? dc->il_n : dc->il_a;
}

static void lane_rest(Lanes *L, const Drive *dc, int q) {
    L->thm[q] = L->wm[q] = L->thu[q] = L->wu[q] = L->cur[q] = 0.0;
    L->trlen[q] = L->ktf[q] = L->ktt[q] = L->trcr[q] = L->integ[q] = 0.0;
    L->trt0[q] = -1.0;
    int64_t m = sector_index(0.0, dc->pp);
    L->m[q] = m;
    L->sec[q] = (double)pymod(m, 6);
    sector_consts(m, dc, &L->thlo[q], &L->kt[q], &L->rp[q], &L->il[q]);
}

/* one plant step of every lane (numba: monitor_lanes._step), after the controller sample
 * under command c if tick */
static inline void lane_step(Lanes *restrict L, const Drive *dcs, const Mech *mcs,
                             const Ctrl *cc0, double h, double c, bool tick, bool cogged,
                             bool eccentric) {
    const Drive *dc0 = &dcs[0];
    const Mech *mc0 = &mcs[0];
    /* model version 2 (libm_trig): libm's scalar sine and cosine in loops of their own */
    if (cogged && dc0->libm)
        for (int q = 0; q < LANES; q++)
            L->tcog[q] = cogging_torque(L->cog[q], L->thm[q] + 0.5 * h * L->wm[q], dc0->pp, true);
    else if (cogged)
        for (int q = 0; q < LANES; q++) {
            double wave = L->cog[q] * poly_sin(6.0 * dc0->pp * (L->thm[q] + 0.5 * h * L->wm[q]));
            L->tcog[q] = L->cog[q] != 0.0 ? wave : 0.0;
        }
    if (eccentric && dc0->libm)
        for (int q = 0; q < LANES; q++) {
            double th = L->thm[q];
            L->kte[q] = kt_eccentric_libm(L->sec[q], th, dc0->ke, L->na[q], L->zeta[q]);
            L->ktm[q] = kt_eccentric_libm(L->sec[q], th + 0.5 * h * L->wm[q], dc0->ke, L->na[q],
                                          L->zeta[q]);
        }
    else if (eccentric)
        for (int q = 0; q < LANES; q++) {
            double th = L->thm[q];
            L->kte[q] = kt_eccentric(L->sec[q], th, dc0->ke, L->na[q], L->zeta[q]);
            L->ktm[q] = kt_eccentric(L->sec[q], th + 0.5 * h * L->wm[q], dc0->ke, L->na[q],
                                     L->zeta[q]);
        }
    for (int q = 0; q < LANES; q++) {   /* controller and the drive inside one sector */
        double i_ref = L->iref[q];
        if (tick) {
            /* ace_update with selects */
            double w_ref = L->kpos[q] * (c - L->fb[q]);
            w_ref = w_ref > cc0->w_max ? cc0->w_max : (w_ref < -cc0->w_max ? -cc0->w_max : w_ref);
            double ew = w_ref - L->wm[q];
            double t_unsat = cc0->kpv * ew + cc0->kiv * L->integ[q];
            double t_ref = t_unsat > cc0->t_max ? cc0->t_max
                           : (t_unsat < -cc0->t_max ? -cc0->t_max : t_unsat);
            bool grow = (t_ref == t_unsat) | ((t_unsat > cc0->t_max) & (ew < 0.0))
                        | ((t_unsat < -cc0->t_max) & (ew > 0.0));
            L->integ[q] = grow ? L->integ[q] + ew * cc0->dtc : L->integ[q];
            i_ref = t_ref * cc0->amps_per_nm;
            L->iref[q] = i_ref;
        }
        bool ecc = L->ecc[q] != 0.0;
        double kt = ecc ? L->kte[q] : L->kt[q];
        double kt_mid = ecc ? L->ktm[q] : kt;
        double cur = L->cur[q], th_m = L->thm[q], w_m = L->wm[q], rp = L->rp[q];
        /* drive_fast */
        double th_lo = L->thlo[q], th_hi = th_lo + dc0->sector_width, th_end = th_m + h * w_m;
        bool fast = (L->trt0[q] + L->trlen[q] <= 0.0) & (th_lo <= th_m) & (th_m < th_hi)
                    & (th_lo <= th_end) & (th_end < th_hi);
        double back = kt * w_m + rp * cur;
        /* _ramp with one division */
        double up = h * (dc0->v_dc - back) * L->il[q];
        double dn = h * (-dc0->v_dc - back) * L->il[q];
        double cur1 = i_ref > cur + up ? cur + up : (i_ref < cur + dn ? cur + dn : i_ref);
        double d = cur1 - cur;
        double f = d * (1.0 / (d > 0.0 ? up : dn));
        double i_mean = cur1 - (0.5 * d) * f;
        double ramp_abs = cur * cur1 >= 0.0 ? 0.5 * fabs(cur + cur1)
                                            : 0.5 * (cur * cur + cur1 * cur1) / fabs(d);
        double i_eq = f * ramp_abs + (1.0 - f) * fabs(cur1);
        double kf = dc0->ktf * kt, km = dc0->ktf * kt_mid;
        fast &= (back < dc0->v_dc) & (-dc0->v_dc < back);
        double t_cog = L->tcog[q];
        L->dslow[q] = fast ? 0.0 : 1.0;
        L->cur[q] = fast ? cur1 : cur;
        L->trt0[q] = fast ? L->trt0[q] - h : L->trt0[q];
        L->tm[q] = km * i_mean + t_cog;
        L->tm0[q] = kf * cur + t_cog;
        L->tm1[q] = km * cur1 + t_cog;
        L->trip[q] = fabs(km) * dc0->half_band;
        L->ieq[q] = i_eq;
    }
    for (int q = 0; q < LANES; q++) {   /* the rest of the drive, lane by lane */
        if (L->dslow[q] == 0.0) continue;
        DState s = {L->cur[q], L->m[q], L->trt0[q], L->trlen[q], L->ktf[q], L->ktt[q],
                    L->trcr[q]};
        DOut o;
        bool ecc = L->ecc[q] != 0.0;
        double kt_hint[2] = {ecc ? L->kte[q] : L->kt[q], ecc ? L->ktm[q] : L->kt[q]};
        drive_step_general(&s, L->iref[q], L->thm[q], L->wm[q], &dcs[q], kt_hint, 0.0, &o);
        L->cur[q] = s.cur; L->m[q] = s.m; L->trt0[q] = s.tr_t0; L->trlen[q] = s.tr_len;
        L->ktf[q] = s.kt_from; L->ktt[q] = s.kt_to; L->trcr[q] = s.tr_cr;
        L->tm[q] = o.t_mean + L->tcog[q];
        L->tm0[q] = o.t_start + L->tcog[q];
        L->tm1[q] = o.t_end + L->tcog[q];
        L->trip[q] = o.t_rip;
        L->ieq[q] = o.i_eq;
        sector_consts(s.m, &dcs[q], &L->thlo[q], &L->kt[q], &L->rp[q], &L->il[q]);
        L->sec[q] = (double)pymod(s.m, 6);
    }
    for (int q = 0; q < LANES; q++) {   /* the sliding mechanics (mech_fast) */
        double th_m = L->thm[q], w_m = L->wm[q], th_u = L->thu[q], w_u = L->wu[q];
        double t_m = L->tm[q], half = L->half[q], tau = mc0->tau;
        double delta = tau * th_m - th_u, dd = tau * w_m - w_u;
        double side = delta > half ? 1.0 : 0.0;
        side = delta < -half ? -1.0 : side;
        double d1 = delta + h * dd;
        double side1 = d1 > half ? 1.0 : 0.0;
        side1 = d1 < -half ? -1.0 : side1;
        double w_stick = mc0->w_stick, th_stop = mc0->th_stop;
        double sgn = w_m > 0.0 ? 1.0 : -1.0;
        double r1 = mc0->jm * w_m - h * (sgn * L->fdyn[q] + 0.5 * L->cm[q] * w_m);
        double r2 = mc0->ju * w_u + h * ((-L->ka[q] * th_u - L->gh[q] * w_u) + 0.0);
        /* _contact_at, moving */
        double off = side > 0.0 ? half : -half;
        double a = L->k[q] * (delta - off) + L->bc[q] * dd;
        double b1 = r1 - h * tau * a, b2 = r2 + h * a;
        double wm_c = (L->i11[q] * b1 + L->i12[q] * b2) + L->i11h[q] * t_m;
        double wu_c = (L->i12[q] * b1 + L->i22[q] * b2) + L->i12h[q] * t_m;
        double t_g = a + L->bc[q] * (tau * wm_c - wu_c);
        double wm_f = r1 * L->imf[q] + L->imfh[q] * t_m;
        double wu_f = r2 * L->iuf[q];
        double wm1 = side != 0.0 ? wm_c : wm_f, wu1 = side != 0.0 ? wu_c : wu_f;
        /* a lane keeps the short path where every condition holds (1.0), else 0.0 */
        double fast = fabs(w_m) >= w_stick ? 1.0 : 0.0;
        fast = fabs(th_u) <= th_stop ? fast : 0.0;
        fast = side1 == side ? fast : 0.0;
        fast = side == 0.0 || t_g * side >= 0.0 ? fast : 0.0;
        fast = wm1 * w_m >= 0.0 ? fast : 0.0;
        double th_m1 = th_m + 0.5 * h * (w_m + wm1);
        double th_u1 = th_u + 0.5 * h * (w_u + wu1);
        bool go = fast != 0.0;
        L->mslow[q] = 1.0 - fast;
        L->thm[q] = go ? th_m1 : th_m;
        L->wm[q] = go ? wm1 : w_m;
        L->thu[q] = go ? th_u1 : th_u;
        L->wu[q] = go ? wu1 : w_u;
        L->a0[q] += go ? 0.5 * (th_u + th_u1) : 0.0;
        L->a1[q] += go ? 0.5 * (th_m + th_m1) : 0.0;
        L->a2[q] += go ? 0.5 * (w_m + wm1) : 0.0;
        L->a3[q] += go ? L->ieq[q] : 0.0;
    }
    for (int q = 0; q < LANES; q++) {   /* the rest of the mechanics, lane by lane */
        if (L->mslow[q] == 0.0) continue;
        MOut o;
        mech_step_general(L->thm[q], L->wm[q], L->thu[q], L->wu[q], L->tm[q], L->tm0[q],
                          L->tm1[q], L->trip[q], 0.0, &mcs[q], &o);
        L->thm[q] = o.th_m; L->wm[q] = o.w_m; L->thu[q] = o.th_u; L->wu[q] = o.w_u;
        L->a0[q] += o.m_th_u; L->a1[q] += o.m_th_m; L->a2[q] += o.m_w_m; L->a3[q] += L->ieq[q];
    }
}

/* every test of the LANES candidates X[idx[q]] (numba: monitor_lanes.lane_group) */
static void lane_group(const double *p, const int64_t *ix, const double *X, const double *E,
                       int64_t n_effects, const int64_t *idx, const double *cmd,
                       const int64_t *cmd_start, const int64_t *n_out, const int64_t *out_start,
                       int64_t n_tests, int64_t total_out, int64_t ticks_out,
                       int64_t steps_tick, double dt, double *out, uint8_t *ok) {
    Lanes L;
    double buf[DBUF][LANES];
    Drive dcs[LANES];
    Mech mcs[LANES];
    double delay[LANES], frac[LANES];
    int64_t d0[LANES];
    bool alive[LANES], done[LANES];
    bool delayed = false, cogged = false, eccentric = false;
    Ctrl cc0 = ace_consts(p, ix, X[4 * idx[0] + 3]);
    memset(&L, 0, sizeof L);
    for (int q = 0; q < LANES; q++) {
        const double *x = X + 4 * idx[q], *e = E + n_effects * idx[q];
        double zeta = e[ix[IDX_E_ECC]], v_dc = p[ix[IDX_VDC]] * (1.0 - e[ix[IDX_E_VSAG]]);
        dcs[q] = drive_consts(p, ix, x[0], zeta, 1.0 + e[ix[IDX_E_RRISE]], v_dc, dt);
        mcs[q] = mech_consts(p, ix, x[1], x[2], e[ix[IDX_E_VISC]], e[ix[IDX_E_AERO]],
                             1.0 - e[ix[IDX_E_GEAR]], dt);
        const Mech *mc = &mcs[q];
        L.cog[q] = e[ix[IDX_E_COG]];
        L.half[q] = mc->half; L.fdyn[q] = mc->fdyn;
        L.k[q] = mc->k; L.cm[q] = mc->cm; L.ka[q] = mc->ka; L.gh[q] = mc->g_h; L.bc[q] = mc->b_c;
        L.i11[q] = mc->i11; L.i12[q] = mc->i12; L.i22[q] = mc->i22; L.i11h[q] = mc->i11h;
        L.i12h[q] = mc->i12h; L.imf[q] = mc->i_m_free; L.imfh[q] = mc->i_m_free_h;
        L.iuf[q] = mc->i_u_free;
        L.ecc[q] = zeta == 0.0 ? 0.0 : 1.0;
        L.zeta[q] = zeta; L.na[q] = dcs[q].na;
        eccentric |= zeta != 0.0;
        cogged |= L.cog[q] != 0.0;
        L.kpos[q] = ace_consts(p, ix, x[3]).k_pos;
        L.off[q] = e[ix[IDX_E_OFFSET]];
        L.gain[q] = 1.0 + e[ix[IDX_E_IGAIN]];
        delay[q] = e[ix[IDX_E_DELAY]] / p[ix[IDX_DTC]];
        d0[q] = (int64_t)floor(delay[q]);
        frac[q] = delay[q] - d0[q];
        delayed |= delay[q] > 0.0;
        done[q] = true;
    }
    double h = dcs[0].h, scale = 1.0 / (ticks_out * steps_tick);
    for (int64_t t = 0; t < n_tests; t++) {
        for (int q = 0; q < LANES; q++) { lane_rest(&L, &dcs[q], q); alive[q] = true; }
        int64_t k_ctrl = cmd_start[t];
        for (int64_t k = 0; k < n_out[t]; k++) {
            for (int q = 0; q < LANES; q++) L.a0[q] = L.a1[q] = L.a2[q] = L.a3[q] = 0.0;
            for (int64_t tk = 0; tk < ticks_out; tk++) {
                for (int q = 0; q < LANES; q++) L.fb[q] = L.thu[q] + L.off[q];
                if (delayed) {   /* _delay_lines */
                    int64_t kk = k_ctrl - cmd_start[t], slot = kk & (DBUF - 1);
                    for (int q = 0; q < LANES; q++) {
                        double fb = L.fb[q];
                        buf[slot][q] = fb;
                        int64_t k0 = kk - d0[q], k1 = k0 - 1;
                        double a = buf[k0 < 0 ? 0 : k0 & (DBUF - 1)][q];
                        double b = buf[k1 < 0 ? 0 : k1 & (DBUF - 1)][q];
                        L.fb[q] = delay[q] > 0.0 ? (1.0 - frac[q]) * a + frac[q] * b : fb;
                    }
                }
                double c = cmd[k_ctrl];
                k_ctrl += 1;
                for (int64_t j = 0; j < steps_tick; j++)
                    lane_step(&L, dcs, mcs, &cc0, h, c, j == 0, cogged, eccentric);
            }
            int64_t row = out_start[t] + k;
            for (int q = 0; q < LANES; q++) {
                double a0 = L.a0[q], a1 = L.a1[q], a2 = L.a2[q], a3 = L.a3[q];
                double *o = out + 4 * (total_out * idx[q] + row);
                o[0] = a0 * scale + L.off[q];
                o[1] = a1 * scale;
                o[2] = a2 * scale;
                o[3] = L.gain[q] * a3 * scale;
                if (alive[q] && !(isfinite(a0) && isfinite(a1) && isfinite(a2) && isfinite(a3))) {
                    alive[q] = false;
                    lane_rest(&L, &dcs[q], q);
                }
            }
        }
        for (int q = 0; q < LANES; q++) done[q] &= alive[q];
    }
    for (int q = 0; q < LANES; q++) ok[idx[q]] = done[q];
}

/* every group of LANES candidates (groups: n_groups x LANES indices; the layout of
 * ema_bench.monitor_lanes.lanes_serial) */
void monitor_lanes_batch(const double *p, const int64_t *ix, const double *X, const double *E,
                         int64_t n_effects, const int64_t *groups, int64_t n_groups,
                         const double *cmd, const int64_t *cmd_start, const int64_t *n_out,
                         const int64_t *out_start, int64_t n_tests, int64_t total_out,
                         int64_t ticks_out, int64_t steps_tick, double dt, double *out,
                         uint8_t *ok) {
    for (int64_t g = 0; g < n_groups; g++)
        lane_group(p, ix, X, E, n_effects, groups + LANES * g, cmd, cmd_start, n_out, out_start,
                   n_tests, total_out, ticks_out, steps_tick, dt, out, ok);
}
