/* Integer square root for firmware images (sonar_app's speed of sound, the random-input
 * benchmark's path lengths): floor(sqrt(v)), bit by bit from v's highest even bit. */
#ifndef MS_ISQRT_H
#define MS_ISQRT_H

#include <stdint.h>

static inline uint64_t ms_isqrt64(uint64_t v)
{
    uint64_t r = 0, b;
    if (!v)
        return 0;
    b = (uint64_t)1 << ((63 - __builtin_clzll(v)) & ~1);
    while (b) {
        if (v >= r + b) {
            v -= r + b;
            r = (r >> 1) + b;
        } else {
            r >>= 1;
        }
        b >>= 2;
    }
    return r;
}

#endif
