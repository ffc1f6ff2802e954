/* Every digit of rs274's canonical calls (LD_PRELOAD, make.sh).
 *
 * The standalone interpreter prints each value with "%.4f": a tenth of a micrometre in mm,
 * 2.5 um in inches, too coarse for a comparison at 1e-6 mm of computed arc centres and inch
 * programs. Its printing goes through __fprintf_chk (Debian builds with _FORTIFY_SOURCE);
 * this replaces that one function, turning each "%.4f" of the format into "%.17g" (enough
 * digits to read the double back exactly) and printing as before. Nothing else changes:
 * canon_to_moves.py checks that a plain run made the same calls with the same values to
 * four decimals.
 */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

int __fprintf_chk(FILE *f, int flag, const char *fmt, ...);

int __fprintf_chk(FILE *f, int flag, const char *fmt, ...)
{
    char wide[2048];
    size_t o = 0;
    const char *p = fmt;
    va_list ap;
    int r;

    (void)flag;
    while (*p && o + 6 < sizeof wide) {
        if (strncmp(p, "%.4f", 4) == 0) {
            memcpy(wide + o, "%.17g", 5);
            o += 5;
            p += 4;
        } else {
            wide[o++] = *p++;
        }
    }
    wide[o] = 0;
    va_start(ap, fmt);
    /* A format longer than the buffer is printed as it is rather than cut. */
    r = vfprintf(f, *p ? fmt : wide, ap);
    va_end(ap);
    return r;
}
