/*
 * The grid index of plan/ink/edges.py, compiled: its cells (cell_keys) and its
 * nearest-edge search (EdgeIndex.nearest_many), with the same double arithmetic as
 * numpy's, so the same answers come out (tests/plan/test_edge_index_native.py holds the
 * two to that, bit for bit). The fill's joins between rings ask for the nearest edge of
 * tens of thousands of points on a large pour: numpy spent 0.5 s on the (point, edge)
 * pairs of hellboard's, this a few hundredths; and the index of all its rings took
 * numpy 0.14 s to sort into cells.
 *
 * Build with -ffp-contract=off and never -ffast-math: a fused multiply-add would round
 * differently from numpy.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

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
 * EdgeIndex.nearest_many: for each query point the nearest edge of the index, searched
 * in a box of `search` nm that doubles until the nearest edge found lies within it (or
 * the box holds the whole grid); ties go to the lowest edge index.
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

/* cell_keys: how many samples the segments take (the most pairs it can return) */
static int64_t samples_of(const int64_t *a, const int64_t *b, int64_t k, int64_t cell) {
    double ax = (double)a[2 * k], ay = (double)a[2 * k + 1];
    double length = hypot((double)b[2 * k] - ax, (double)b[2 * k + 1] - ay);
    double parts = ceil(length / ((double)cell / 2.0));
    return (parts > 1.0 ? (int64_t)parts : 1) + 1;
}

int64_t cell_samples(int64_t count, const int64_t *a, const int64_t *b, int64_t cell) {
    int64_t total = 0;
    for (int64_t k = 0; k < count; k++)
        total += samples_of(a, b, k, cell);
    return total;
}

/* keep pairs that differ from the one before; returns how many are left */
static int64_t drop_repeats(int64_t *keys, int64_t *owners, int64_t n) {
    int64_t kept = 0;
    for (int64_t k = 0; k < n; k++) {
        if (kept && keys[k] == keys[kept - 1] && owners[k] == owners[kept - 1])
            continue;
        keys[kept] = keys[k];
        owners[kept] = owners[k];
        kept++;
    }
    return kept;
}

/*
 * edges.cell_keys: the cells of segments a[k]-b[k] sampled half a cell apart, as
 * distinct (cell key, k) pairs sorted by key, then k, in keys and owners (room for
 * cell_samples pairs). Returns how many, or -1 without memory. The pairs come in k
 * order, so a stable sort by key (radix, 11 bits a pass) puts them in (key, k) order.
 */
int64_t cell_keys(int64_t count, const int64_t *a, const int64_t *b, int64_t cell,
                  int64_t *keys, int64_t *owners) {
    int64_t n = 0;
    for (int64_t k = 0; k < count; k++) {
        double ax = (double)a[2 * k], ay = (double)a[2 * k + 1];
        double dx = (double)b[2 * k] - ax, dy = (double)b[2 * k + 1] - ay;
        int64_t samples = samples_of(a, b, k, cell);
        for (int64_t s = 0; s < samples; s++) {
            double t = (double)s / (double)(samples - 1);
            int64_t column = (int64_t)floor((ax + dx * t) / (double)cell);
            int64_t row = (int64_t)floor((ay + dy * t) / (double)cell);
            keys[n] = key_of(column, row);
            owners[n] = k;
            n++;
        }
    }
    n = drop_repeats(keys, owners, n);   /* neighbouring samples mostly share a cell */
    if (n < 2)
        return n;
    int64_t low = keys[0], high = keys[0];
    for (int64_t k = 1; k < n; k++) {
        if (keys[k] < low) low = keys[k];
        if (keys[k] > high) high = keys[k];
    }
    uint64_t span = (uint64_t)(high - low);
    int64_t *other_keys = malloc((size_t)n * sizeof(int64_t));
    int64_t *other_owners = malloc((size_t)n * sizeof(int64_t));
    int64_t *counts = malloc(2048 * sizeof(int64_t));
    if (!other_keys || !other_owners || !counts) {
        free(other_keys);
        free(other_owners);
        free(counts);
        return -1;
    }
    int64_t *from_keys = keys, *from_owners = owners, *to_keys = other_keys,
            *to_owners = other_owners;
    for (int shift = 0; shift < 64 && (span >> shift) != 0; shift += 11) {
        memset(counts, 0, 2048 * sizeof(int64_t));
        for (int64_t k = 0; k < n; k++)
            counts[((uint64_t)(from_keys[k] - low) >> shift) & 2047]++;
        int64_t at = 0;
        for (int d = 0; d < 2048; d++) {
            int64_t c = counts[d];
            counts[d] = at;
            at += c;
        }
        for (int64_t k = 0; k < n; k++) {
            int64_t place = counts[((uint64_t)(from_keys[k] - low) >> shift) & 2047]++;
            to_keys[place] = from_keys[k];
            to_owners[place] = from_owners[k];
        }
        int64_t *swap = from_keys; from_keys = to_keys; to_keys = swap;
        swap = from_owners; from_owners = to_owners; to_owners = swap;
    }
    if (from_keys != keys) {
        memcpy(keys, from_keys, (size_t)n * sizeof(int64_t));
        memcpy(owners, from_owners, (size_t)n * sizeof(int64_t));
    }
    free(other_keys);
    free(other_owners);
    free(counts);
    return drop_repeats(keys, owners, n);
}
