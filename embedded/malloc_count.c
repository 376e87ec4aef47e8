/* Counting heap allocations (Linux/glibc): a check of the no-heap rule, not part of a robot.
 *
 *   cc -O2 -fPIC -shared embedded/malloc_count.c -o malloc_count.so -ldl
 *   LD_PRELOAD=./malloc_count.so ./mmstab_loop run.bin      # prints "heap_allocations: N"
 *
 * Runs of different lengths allocate the same number of blocks exactly when the loop itself
 * allocates nothing (mmstab's tests do this with the qrqp plugin).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stddef.h>
#include <stdio.h>

static long count = 0;

void* malloc(size_t size) {
  static void* (*real)(size_t) = 0;
  if (!real) *(void**)(&real) = dlsym(RTLD_NEXT, "malloc");
  ++count;
  return real(size);
}

void* calloc(size_t n, size_t size) {
  static void* (*real)(size_t, size_t) = 0;
  if (!real) {
    /* dlsym may itself calloc: serve that one from a static block */
    static char bootstrap[256];
    static int busy = 0;
    if (busy) return size * n <= sizeof bootstrap ? bootstrap : 0;
    busy = 1;
    *(void**)(&real) = dlsym(RTLD_NEXT, "calloc");
    busy = 0;
  }
  ++count;
  return real(n, size);
}

void* realloc(void* p, size_t size) {
  static void* (*real)(void*, size_t) = 0;
  if (!real) *(void**)(&real) = dlsym(RTLD_NEXT, "realloc");
  ++count;
  return real(p, size);
}

__attribute__((destructor)) static void report(void) {
  fprintf(stderr, "heap_allocations: %ld\n", count);
}
