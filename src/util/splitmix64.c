/* SplitMix64 (G. L. Steele, D. Lea and C. H. Flood, "Fast splittable pseudorandom number
 * generators", OOPSLA 2014; the form of S. Vigna's public-domain splitmix64.c, the generator
 * that seeds xoshiro): a 64-bit state advanced by the golden-ratio increment 0x9e3779b97f4a7c15
 * and mixed by two xor-shift-multiply rounds. Written in C because it needs arithmetic modulo
 * 2^64, which C's uint64_t defines and Fortran's signed integers do not: the same seed gives the
 * same numbers on every machine and compiler. Called from src/util/seeded_random.f90. */
#include <stdint.h>

/* `count` numbers uniform in [0, 1) from `seed`: the top 53 bits of each output times 2^-53. */
void eme_splitmix64_uniform(uint64_t seed, long count, double *values)
{
    uint64_t state = seed;
    for (long i = 0; i < count; ++i) {
        uint64_t z = (state += UINT64_C(0x9e3779b97f4a7c15));
        z = (z ^ (z >> 30)) * UINT64_C(0xbf58476d1ce4e5b9);
        z = (z ^ (z >> 27)) * UINT64_C(0x94d049bb133111eb);
        z ^= z >> 31;
        values[i] = (double)(z >> 11) * 0x1.0p-53;
    }
}
