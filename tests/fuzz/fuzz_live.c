/* fuzz_live.c — crom-live's commands (lib/rom/live.c crom_live_parse): the
 * input is the text a FIFO or stdin brings, one command per line. Every
 * line parses or is refused with a message; one that parses must be a known
 * command with a terminated reference, finite numbers, a stiffness that is
 * 0 (the default) or positive, and a step count in range. */
#include <math.h>
#include <string.h>

#include "base/err.h"
#include "rom/live.h"

#include "fuzz.h"

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_quiet_stdout();
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char line[512];
    size_t i = 0;
    while (i < size) {
        size_t n = 0;
        while (i < size && data[i] != '\n' && n + 1 < sizeof line)
            line[n++] = (char)data[i++];
        if (i < size && data[i] == '\n')
            i++;
        line[n] = 0;
        crom_live_cmd c;
        int rc = crom_live_parse(line, &c);
        if (rc == 0) {
            if ((int)c.kind < CROM_LIVE_NONE || c.kind > CROM_LIVE_QUIT || !memchr(c.ref, 0, sizeof c.ref) ||
                !isfinite(c.v[0]) || !isfinite(c.v[1]) || !isfinite(c.v[2]) || !(c.k == 0 || c.k > 0) ||
                (c.kind == CROM_LIVE_STEP && (c.n < 1 || c.n > 100000000L))) {
                fprintf(stderr, "bad command parsed from '%s': kind %d\n", line, (int)c.kind);
                abort();
            }
        } else if (rc != CROM_EUSAGE || !crom_errmsg()[0]) {
            fprintf(stderr, "'%s': code %d without a usage message\n", line, rc);
            abort();
        }
        crom_err_clear();
    }
    return 0;
}
