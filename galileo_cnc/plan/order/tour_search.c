/*
 * The local search of tour.py (Tour.improve and Tour.perturb), compiled: the same
 * moves in the same order with the same double arithmetic, so the same tour comes out
 * (tests/plan/test_tour_native.py holds the two to that on random and corpus
 * instances). Python draws the perturbation's random numbers (they never depend on the
 * tour) and passes them in. Built by setup.py as an optional extension; tour.py
 * runs its own Python where it is missing.
 *
 * Build with -ffp-contract=off and never -ffast-math: a fused multiply-add or a
 * reordered sum would round differently from Python.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define EPS 1e-3

typedef struct {
    int64_t m;
    const double *xs, *ys, *tail;
    const int64_t *cand_at;      /* node u's candidates: cand[cand_at[u] .. cand_at[u+1]) */
    const int64_t *cand;
    const double *cand_d;
    int64_t *tour, *pos;
    double *travel;
    uint8_t *queued;
    /* the queue: a ring buffer */
    int64_t *queue;
    int64_t q_cap, q_head, q_len;
    /* the reversals since a perturbation (undone if it gained nothing) */
    int64_t *log;
    int64_t log_len, log_cap;
    int logging;
    /* the nodes whose travel edges changed since a perturbation */
    int64_t *touched;
    int64_t touched_len, touched_cap;
    int touching;
    double gained;
    int failed;                  /* out of memory */
} Tour;

static int64_t wrap(int64_t i, int64_t m) {
    int64_t r = i % m;
    return r < 0 ? r + m : r;
}

static double dist(const Tour *t, int64_t a, int64_t b) {
    if (a == 1 || b == 1)
        return t->tail[a + b - 1];
    double dx = t->xs[a] - t->xs[b];
    double dy = t->ys[a] - t->ys[b];
    return sqrt(dx * dx + dy * dy);
}

static int grow(int64_t **items, int64_t *cap, int64_t need) {
    if (need <= *cap)
        return 1;
    int64_t size = *cap ? *cap : 64;
    while (size < need)
        size *= 2;
    int64_t *bigger = realloc(*items, (size_t)size * sizeof(int64_t));
    if (!bigger)
        return 0;
    *items = bigger;
    *cap = size;
    return 1;
}

static void push(Tour *t, int64_t v) {
    t->queue[(t->q_head + t->q_len) % t->q_cap] = v;
    t->q_len++;
}

static int64_t pop(Tour *t) {
    int64_t v = t->queue[t->q_head];
    t->q_head = (t->q_head + 1) % t->q_cap;
    t->q_len--;
    return v;
}

/* Tour._reverse */
static void reverse(Tour *t, int64_t i, int64_t j) {
    int64_t m = t->m;
    if (t->logging) {
        if (!grow(&t->log, &t->log_cap, t->log_len + 2)) {
            t->failed = 1;
            return;
        }
        t->log[t->log_len++] = i;
        t->log[t->log_len++] = j;
    }
    int64_t length = wrap(j - i, m) + 1;
    if (2 * length > m) {
        int64_t ni = (j + 1) % m, nj = wrap(i - 1, m);
        i = ni;
        j = nj;
        length = m - length;
    }
    for (int64_t k = 0; k < length / 2; k++) {
        int64_t a = t->tour[i], b = t->tour[j];
        t->tour[i] = b;
        t->tour[j] = a;
        t->pos[b] = i;
        t->pos[a] = j;
        if (++i == m)
            i = 0;
        if (--j < 0)
            j = m - 1;
    }
}

/* Tour._move2 */
static void move2(Tour *t, int64_t a, int64_t b, int64_t c, int64_t d) {
    int64_t m = t->m, pa = t->pos[a], pb = t->pos[b];
    if (pb == pa + 1 || (pb == 0 && pa == m - 1))
        reverse(t, pb, t->pos[c]);
    else
        reverse(t, pa, t->pos[d]);
}

/* Tour._insert */
static void insert(Tour *t, int64_t v, int64_t vp, int64_t e, int64_t en, int64_t u,
                   int64_t up) {
    int64_t m = t->m;
    int forward = t->tour[wrap(t->pos[v] - 1, m)] == vp;
    int64_t pu = t->pos[u];
    int after_u = t->tour[pu + 1 < m ? pu + 1 : 0] == up;
    int64_t x, y;
    if (after_u == forward) {
        x = u;
        y = up;
    } else {
        x = up;
        y = u;
    }
    move2(t, vp, v, x, y);
    move2(t, vp, x, en, e);
    if (u == x)
        move2(t, x, e, v, y);
}

/* the improve's partner(v): its travel partner, and +1 if it follows v else -1 */
static int64_t partner(const Tour *t, int64_t v, int *side) {
    int64_t m = t->m, p = t->pos[v];
    int64_t s = t->tour[p + 1 < m ? p + 1 : 0];
    if (s == (v ^ 1)) {
        *side = -1;
        return t->tour[wrap(p - 1, m)];
    }
    *side = 1;
    return s;
}

static void changed(Tour *t, const int64_t *nodes, int count) {
    for (int k = 0; k < count; k++) {
        int64_t v = nodes[k];
        int side;
        int64_t w = partner(t, v, &side);
        t->travel[v] = dist(t, v, w);
        if (t->touching) {
            if (!grow(&t->touched, &t->touched_cap, t->touched_len + 1)) {
                t->failed = 1;
                return;
            }
            t->touched[t->touched_len++] = v;
        }
        if (!t->queued[v]) {
            t->queued[v] = 1;
            push(t, v);
        }
    }
}

/* Tour.improve on the queue as it is: the candidates tried */
static int64_t improve(Tour *t, int64_t budget) {
    int64_t m = t->m, pairs = m / 2;
    int64_t tries = 0;
    double gained = 0.0;
    while (t->q_len && tries < budget && !t->failed) {
        int64_t u = pop(t);
        t->queued[u] = 0;
        if (u == 1)
            continue;
        int uside;
        int64_t up = partner(t, u, &uside);
        double duu = t->travel[u];
        int64_t pu = t->pos[u];
        for (int64_t c = t->cand_at[u]; c < t->cand_at[u + 1]; c++) {
            int64_t v = t->cand[c];
            double duv = t->cand_d[c];
            tries++;
            double g1 = duu - duv;
            if (g1 <= EPS)
                break;
            if (v == up)
                continue;
            int vside;
            int64_t vp = partner(t, v, &vside);
            double base = g1 + t->travel[v];
            if (uside == vside) {
                double gain = base - dist(t, up, vp);
                if (gain > EPS) {
                    move2(t, u, up, v, vp);
                    gained += gain;
                    int64_t nodes[4] = {u, up, v, vp};
                    changed(t, nodes, 4);
                    break;
                }
            }
            /* Or-opt, both ways round (see tour.py) */
            int have = 0;
            double best_gain = 0.0;
            int64_t best[6] = {0, 0, 0, 0, 0, 0};
            int64_t q = t->pos[v];
            for (int way = 0; way < 2; way++) {
                int64_t a = way ? u : v, ap = way ? up : vp, b = way ? v : u,
                        bp = way ? vp : up, pa = way ? pu : q;
                int aside = way ? uside : vside;
                int64_t step = -aside;
                int64_t pb = t->pos[b];
                for (int64_t length = 1; length < 4; length++) {
                    if (length + 2 > pairs)
                        break;
                    int64_t pe = wrap(pa + step * (2 * length - 1), m);
                    if (wrap((pb - pa) * step, m) < 2 * length ||
                        wrap((t->pos[bp] - pa) * step, m) < 2 * length)
                        break;
                    int64_t e = t->tour[pe], en = t->tour[wrap(pe + step, m)];
                    double gain;
                    if (ap == 1 || en == 1) {
                        gain = base + t->travel[e] - t->tail[ap + en - 1];
                    } else {
                        double dx = t->xs[ap] - t->xs[en];
                        double dy = t->ys[ap] - t->ys[en];
                        gain = base + t->travel[e] - sqrt(dx * dx + dy * dy);
                    }
                    if (gain <= EPS)
                        continue;
                    if (e != 1 && bp != 1) {
                        double dx = t->xs[e] - t->xs[bp];
                        double dy = t->ys[e] - t->ys[bp];
                        gain -= sqrt(dx * dx + dy * dy);
                    } else {
                        gain -= t->tail[e + bp - 1];
                    }
                    if (gain > EPS && (!have || gain > best_gain)) {
                        have = 1;
                        best_gain = gain;
                        best[0] = a; best[1] = ap; best[2] = e;
                        best[3] = en; best[4] = b; best[5] = bp;
                    }
                }
            }
            if (have) {
                insert(t, best[0], best[1], best[2], best[3], best[4], best[5]);
                gained += best_gain;
                changed(t, best, 6);
                break;
            }
        }
    }
    while (t->q_len)                     /* out of budget: leave no flag set */
        t->queued[pop(t)] = 0;
    t->gained = gained;
    return tries;
}

/* Tour._refresh */
static void refresh(Tour *t, const int64_t *nodes, int64_t count) {
    int64_t m = t->m;
    for (int64_t k = 0; k < count; k++) {
        int64_t v = nodes[k], p = t->pos[v];
        int64_t w = t->tour[p + 1 < m ? p + 1 : 0];
        if (w == (v ^ 1))
            w = t->tour[wrap(p - 1, m)];
        t->travel[v] = dist(t, v, w);
    }
}

/*
 * Tour.improve from every node (within `budget` candidates), then Tour.perturb
 * `count` times within what is left; draws[3k .. 3k+2] are the k-th perturbation's
 * rng.randrange(m), rng.randint(1, most), rng.randint(1, most). Returns the
 * candidates tried in all, or -1 when out of memory (the tour is then undefined).
 */
int64_t tour_search(int64_t m, const double *xs, const double *ys, const double *tail,
                    const int64_t *cand_at, const int64_t *cand, const double *cand_d,
                    int64_t *tour, int64_t *pos, double *travel, int64_t budget,
                    int64_t count, const int64_t *draws) {
    Tour t;
    memset(&t, 0, sizeof t);
    t.m = m;
    t.xs = xs; t.ys = ys; t.tail = tail;
    t.cand_at = cand_at; t.cand = cand; t.cand_d = cand_d;
    t.tour = tour; t.pos = pos; t.travel = travel;
    t.queued = calloc((size_t)m, 1);
    t.q_cap = 2 * m + 16;
    t.queue = malloc((size_t)t.q_cap * sizeof(int64_t));
    if (!t.queued || !t.queue) {
        free(t.queued);
        free(t.queue);
        return -1;
    }
    for (int64_t v = 0; v < m; v++) {
        t.queued[v] = 1;
        push(&t, v);
    }
    int64_t tries = improve(&t, budget);
    int64_t spent = tries;
    budget -= tries;
    int64_t pairs = m / 2;
    if (pairs >= 4) {
        for (int64_t k = 0; k < count && !t.failed; k++) {
            if (budget <= 0)
                break;
            budget -= 1;
            int64_t start = draws[3 * k];
            if (tour[(start + 1) % m] == (tour[start] ^ 1))
                start = (start + 1) % m;
            int64_t l1 = draws[3 * k + 1], l2 = draws[3 * k + 2];
            int64_t p1 = start, p2 = (p1 + 2 * l1) % m, p3 = (p2 + 2 * l2) % m;
            int64_t a = tour[p1], b = tour[(p1 + 1) % m];
            int64_t c = tour[p2], d = tour[(p2 + 1) % m];
            int64_t e = tour[p3], f = tour[(p3 + 1) % m];
            double delta = (dist(&t, a, d) + dist(&t, e, b) + dist(&t, c, f)
                            - dist(&t, a, b) - dist(&t, c, d) - dist(&t, e, f));
            int64_t six[6] = {a, b, c, d, e, f};
            t.logging = 1;
            t.log_len = 0;
            t.touching = 1;
            t.touched_len = 0;
            if (!grow(&t.touched, &t.touched_cap, 6)) {
                t.failed = 1;
                break;
            }
            memcpy(t.touched, six, sizeof six);
            t.touched_len = 6;
            reverse(&t, (p1 + 1) % m, p3);
            int64_t firsts[2] = {e, c}, lasts[2] = {d, b};
            int64_t nodes[2] = {wrap(p3 - p2, m), wrap(p2 - p1, m)};
            for (int k2 = 0; k2 < 2; k2++) {
                int64_t first = firsts[k2], last = lasts[k2];
                if (wrap(pos[last] - pos[first], m) == nodes[k2] - 1)
                    reverse(&t, pos[first], pos[last]);
                else
                    reverse(&t, pos[last], pos[first]);
            }
            refresh(&t, six, 6);
            for (int k2 = 0; k2 < 6; k2++) {
                t.queued[six[k2]] = 1;
                push(&t, six[k2]);
            }
            int64_t used = improve(&t, budget);
            budget -= used;
            spent += used;
            if (t.gained - delta <= EPS) {
                t.logging = 0;
                for (int64_t r = t.log_len - 2; r >= 0; r -= 2)
                    reverse(&t, t.log[r], t.log[r + 1]);
                refresh(&t, t.touched, t.touched_len);
            }
            t.logging = 0;
            t.touching = 0;
        }
    }
    int failed = t.failed;
    free(t.queued);
    free(t.queue);
    free(t.log);
    free(t.touched);
    return failed ? -1 : spent;
}
