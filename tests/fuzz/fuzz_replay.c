/* fuzz_replay — runs a libFuzzer harness over files, without libFuzzer.
 *
 * Usage: fuzz_replay_HARNESS FILE...   ($LUMESH_FUZZ_EXT as for the harness)
 *
 * Linked with one harness, this is how ctest keeps the harnesses compiling and
 * replays the bad-input corpus and the fuzzing seeds through them in every build
 * (the ASan/UBSan one included) without clang: a crash, leak or trap fails it.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "src/base/util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int main(int argc, char **argv)
{
    int failed = 0;
    for (int i = 1; i < argc; ++i) {
        char *data = NULL;
        size_t size = 0;
        lm_error err;
        if (lm_read_file(argv[i], 0, &data, &size, &err) != LM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            failed = 1;
            continue;
        }
        LLVMFuzzerTestOneInput((const uint8_t *)data, size);
        free(data);
    }
    printf("replayed %d file%s\n", argc - 1, argc == 2 ? "" : "s");
    return failed;
}
