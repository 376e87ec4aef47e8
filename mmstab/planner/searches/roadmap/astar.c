/* A* over the posture roadmap (mmstab.planner.searches.roadmap.moves.astar), in C.
 *
 * The same search as the Python loop, operation for operation, so the same path: the
 * heuristic is the lattice L1 distance to the goal summed joint by joint from 0.0; the
 * open list is a binary heap ordered by (f, -g, node), a total order on its entries (a
 * node is pushed again only with a strictly lower cost), so it pops them in the order
 * Python's heapq does; an entry whose cost is above the node's best is stale and skipped;
 * a neighbour is relaxed when its cost is strictly lower and it is not masked; at most
 * `expansions` pops, then no path.
 *
 * The graph: CSR (indptr N + 1, indices, weights) of N nodes; q (N, J) the postures.
 * best (N, +inf) and parent (N) are the caller's work arrays: every entry this call
 * touches is set back to +inf before it returns, so they are reused call after call.
 * masked: N bytes (1: never entered) or NULL.
 * Out: path (at most N nodes, a -> b); returns its length, 0 when the expansions ran out
 * before b, -2 when the open list emptied first (b cannot be reached: no path, proved),
 * -1 when memory ran out. */
#include <math.h>
#include <stdlib.h>

typedef struct {
    double f, g;
    long n;
} Entry;

static int before(const Entry *x, const Entry *y)
{
    if (x->f != y->f)
        return x->f < y->f;
    if (x->g != y->g)
        return x->g > y->g; /* -g ascending */
    return x->n < y->n;
}

static void push(Entry *heap, long *size, Entry e)
{
    long i = (*size)++;
    while (i > 0) {
        long up = (i - 1) / 2;
        if (!before(&e, &heap[up]))
            break;
        heap[i] = heap[up];
        i = up;
    }
    heap[i] = e;
}

static Entry pop(Entry *heap, long *size)
{
    Entry top = heap[0], last = heap[--(*size)];
    long i = 0, n = *size;
    for (;;) {
        long c = 2 * i + 1;
        if (c >= n)
            break;
        if (c + 1 < n && before(&heap[c + 1], &heap[c]))
            c++;
        if (!before(&heap[c], &last))
            break;
        heap[i] = heap[c];
        i = c;
    }
    if (n)
        heap[i] = last;
    return top;
}

static double l1(const double *q, long J, long n, long b)
{
    double s = 0.0;
    for (long j = 0; j < J; j++)
        s += fabs(q[n * J + j] - q[b * J + j]);
    return s;
}

long mmstab_astar(const long *indptr, const long *indices, const double *weights,
                  const double *q, long N, long J, long a, long b,
                  const unsigned char *masked, long expansions, double *best,
                  long *parent, long *path)
{
    long cap = 1024, size = 0, touched_cap = 1024, touched = 0, found = 0, length = 0;
    Entry *heap = malloc(cap * sizeof(Entry));
    long *seen = malloc(touched_cap * sizeof(long));
    if (!heap || !seen) {
        free(heap);
        free(seen);
        return -1;
    }
    (void)N;
    best[a] = 0.0;
    parent[a] = a;
    seen[touched++] = a;
    push(heap, &size, (Entry){l1(q, J, a, b), 0.0, a});
    for (long it = 0; it < expansions && size > 0; it++) {
        Entry e = pop(heap, &size);
        long n = e.n;
        if (n == b) {
            found = 1;
            break;
        }
        if (e.g > best[n])
            continue; /* a stale entry */
        for (long k = indptr[n]; k < indptr[n + 1]; k++) {
            long m = indices[k];
            double cost = best[n] + weights[k];
            if (cost < best[m] && !(masked && masked[m])) {
                if (best[m] == INFINITY) {
                    if (touched == touched_cap) {
                        long *grown = realloc(seen, 2 * touched_cap * sizeof(long));
                        if (!grown) {
                            length = -1;
                            goto done;
                        }
                        seen = grown;
                        touched_cap *= 2;
                    }
                    seen[touched++] = m;
                }
                best[m] = cost;
                parent[m] = n;
                if (size == cap) {
                    Entry *grown = realloc(heap, 2 * cap * sizeof(Entry));
                    if (!grown) {
                        length = -1;
                        goto done;
                    }
                    heap = grown;
                    cap *= 2;
                }
                push(heap, &size, (Entry){cost + l1(q, J, m, b), cost, m});
            }
        }
    }
    if (!found && size == 0)
        length = -2; /* every node a reaches expanded, b not among them */
    if (found) { /* b back to a, then reversed */
        long n = b;
        path[length++] = n;
        while (n != a) {
            n = parent[n];
            path[length++] = n;
        }
        for (long i = 0, j = length - 1; i < j; i++, j--) {
            long t = path[i];
            path[i] = path[j];
            path[j] = t;
        }
    }
done:
    for (long i = 0; i < touched; i++)
        best[seen[i]] = INFINITY;
    free(heap);
    free(seen);
    return length;
}
