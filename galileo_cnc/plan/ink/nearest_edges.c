/*
 * EdgeIndex.nearest_many (plan/ink/edges.py), compiled: for each query point the
 * nearest edge of the grid index, searched in a box of `search` nm that doubles until
 * the nearest edge found lies within it (or the box holds the whole grid). The same
 * cells, the same double arithmetic as edges.point_to_edges and the same ties (the
 * lowest edge index among equally near ones), so the same answers come out
 * (tests/plan/test_nearest_native.py holds the two to that). The fill's joins between
 * rings ask it for tens of thousands of points on a large pour: numpy spent 0.5 s on
 * the (point, edge) pairs of hellboard's, this a few hundredths.
 *
 * Build with -ffp-contract=off and never -ffast-math: a fused multiply-add would round
 * differently from numpy.
 */
#include <math.h>
#include <stdint.h>

#define KEY ((int64_t)1 << 31) /* edges.py's _KEY: cell key = column * KEY + row */

static int64_t floor_div(int64_t a, int64_t c) { /* c > 0: numpy's floor_divide */
    int64_t q = a / c;
    return (a % c != 0 && a < 0) ? q - 1 : q;
}

static int64_t key_of(int64_t column, int64_t row) {
    return (column + KEY / 2) * KEY + (row + KEY / 2);
}

/* the first index in keys[0 .. n) whose key is >= key */
static int64_t lower_bound(const int64_t *keys, int64_t n, int64_t key) {
    int64_t lo = 0, hi = n;
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if (keys[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/*
 * points: (count, 2) int64; keys, members: the index's sorted (cell key, edge) pairs;
 * a, b: (edges, 2) int64 ends; grid: lowest column, row, highest column, row holding
 * an edge. Out: per point its edge, t along it and distance.
 */
void nearest_edges(int64_t count, const int64_t *points, int64_t search, int64_t cell,
                   int64_t pairs, const int64_t *keys, const int64_t *members,
                   const int64_t *a, const int64_t *b, const int64_t *grid,
                   int64_t *edge_out, double *t_out, double *distance_out) {
    for (int64_t k = 0; k < count; k++) {
        int64_t x = points[2 * k], y = points[2 * k + 1];
        double px = (double)x, py = (double)y;
        int64_t radius = search > cell ? search : cell;
        for (;;) {
            int64_t x0 = floor_div(x - radius, cell) - 1, y0 = floor_div(y - radius, cell) - 1;
            int64_t x1 = floor_div(x + radius, cell) + 1, y1 = floor_div(y + radius, cell) + 1;
            int everything = x0 <= grid[0] && y0 <= grid[1] && x1 >= grid[2] && y1 >= grid[3];
            /* no edge lies in a cell outside the grid's bounds */
            if (x0 < grid[0]) x0 = grid[0];
            if (y0 < grid[1]) y0 = grid[1];
            if (x1 > grid[2]) x1 = grid[2];
            if (y1 > grid[3]) y1 = grid[3];
            int found = 0;
            int64_t best_edge = INT64_MAX;
            double best_t = 0.0, best_d = INFINITY;
            for (int64_t column = x0; column <= x1 && y0 <= y1; column++) {
                /* a column's cells y0 .. y1 have consecutive keys */
                int64_t last = key_of(column, y1);
                for (int64_t at = lower_bound(keys, pairs, key_of(column, y0));
                     at < pairs && keys[at] <= last; at++) {
                    int64_t e = members[at];
                    /* edges.point_to_edges, operation for operation */
                    double ax = (double)a[2 * e], ay = (double)a[2 * e + 1];
                    double dx = (double)b[2 * e] - ax, dy = (double)b[2 * e + 1] - ay;
                    double length2 = dx * dx + dy * dy;
                    double t = ((px - ax) * dx + (py - ay) * dy) / (length2 > 0 ? length2 : 1.0);
                    t = t > 0.0 ? (t < 1.0 ? t : 1.0) : 0.0; /* np.clip's, -0.0 too */
                    double d = hypot((ax + dx * t) - px, (ay + dy * t) - py);
                    found = 1;
                    if (d < best_d || (d == best_d && e < best_edge)) {
                        best_d = d;
                        best_edge = e;
                        best_t = t;
                    }
                }
            }
            /* only an edge within the searched radius is surely the nearest */
            if (found && (best_d <= (double)radius || everything)) {
                edge_out[k] = best_edge;
                t_out[k] = best_t;
                distance_out[k] = best_d;
                break;
            }
            radius *= 2;
        }
    }
}
