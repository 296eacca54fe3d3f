/* scene_badinput_test — the bad-input corpus (tests/badinput/expect.txt) through
 * the library: each file fails with a code the CLI maps to exit 2, and with one
 * line that names the file and contains the expected words. Run under
 * ASan/UBSan in CI, so a crash or a leak on any of them fails too. Files the
 * manifest gives exit code 0 are accepted with a note in the load report (the
 * documented acceptance: e.g. a number below float's range read as 0). */
#define _POSIX_C_SOURCE 200809L /* mkfifo, alarm */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "src/image/image.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

/* An image `lumesh compare` must refuse: img_read fails with one line. */
static void run_image_case(const char *file, const char *fragment, const char *name)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/badinput/%s", LUMESH_TEST_DIR, file);
    img_image img = {0};
    lm_error err;
    memset(&err, 0, sizeof err);
    lm_result r = img_read(path, &img, &err);
    CHECK_MSG(r == LM_ERR_BAD_INPUT, "%s: result %s (%s)", file, lm_result_name(r), err.msg);
    CHECK_MSG(strstr(err.msg, fragment) != NULL, "%s: message '%s' lacks '%s'", file, err.msg, fragment);
    CHECK_MSG(strstr(err.msg, name) != NULL, "%s: message '%s' does not name '%s'", file, err.msg, name);
    CHECK_MSG(strchr(err.msg, '\n') == NULL, "%s: message has more than one line", file);
    printf("  %-38s image  %s\n", file, err.msg);
    img_free(&img);
}

static void run_case(const char *file, const char *command, const char *fragment, const char *name)
{
    if (strcmp(command, "compare") == 0) {
        run_image_case(file, fragment, name);
        return;
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/badinput/%s", LUMESH_TEST_DIR, file);
    scene_load_desc d = {.path = path, .require_light = strcmp(command, "render") == 0};
    scene *s = NULL;
    lm_error err;
    memset(&err, 0, sizeof err);
    double t0 = lm_now_seconds();
    lm_result r = scene_load(&d, &s, &err);
    double dt = lm_now_seconds() - t0;
    CHECK_MSG(r == LM_ERR_BAD_INPUT || r == LM_ERR_IO, "%s: result %s (%s)", file, lm_result_name(r),
              err.msg);
    CHECK_MSG(s == NULL, "%s: a scene was returned on failure", file);
    if (s) scene_destroy(s);
    CHECK_MSG(strstr(err.msg, fragment) != NULL, "%s: message '%s' lacks '%s'", file, err.msg, fragment);
    CHECK_MSG(strstr(err.msg, name) != NULL, "%s: message '%s' does not name '%s'", file, err.msg, name);
    CHECK_MSG(strchr(err.msg, '\n') == NULL, "%s: message has more than one line", file);
    printf("  %-38s %6.1f ms  %s\n", file, dt * 1e3, err.msg);
}

/* A file the loaders accept with a note (exit code 0 in the manifest): it loads,
 * and one of its report's notes names the file and holds the expected words. */
static void run_accepted(const char *file, const char *fragment, const char *name)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/badinput/%s", LUMESH_TEST_DIR, file);
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&(scene_load_desc){.path = path}, &s, &err);
    CHECK_MSG(r == LM_OK, "%s: %s", file, err.msg);
    int noted = 0;
    for (uint32_t i = 0; s && i < s->report.note_count; ++i)
        if (strstr(s->report.notes[i], fragment) && strstr(s->report.notes[i], name)) {
            noted = 1;
            printf("  %-38s accepted: %s\n", file, s->report.notes[i]);
        }
    CHECK_MSG(noted, "%s: no note with '%s' naming '%s'", file, fragment, name);
    scene_destroy(s);
}

/* A named pipe given as a scene or an image: an error at once, not an open that
 * waits for a writer forever (alarm: a hang fails the test). */
static void check_fifo(void)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/badinput-fifo.obj", LUMESH_TMP_DIR);
    unlink(path);
    if (mkfifo(path, 0600) != 0) {
        printf("  (no FIFO here: %s)\n", strerror(errno));
        return;
    }
    alarm(20);
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&(scene_load_desc){.path = path}, &s, &err);
    CHECK_MSG(r == LM_ERR_IO && strstr(err.msg, "not a regular file"), "FIFO scene: %s", err.msg);
    scene_destroy(s);
    img_image img = {0};
    r = img_read(path, &img, &err);
    CHECK_MSG(r == LM_ERR_IO && strstr(err.msg, "not a regular file"), "FIFO image: %s", err.msg);
    img_free(&img);
    alarm(0);
    printf("  %-38s refused: %s\n", "a named pipe", err.msg);
    unlink(path);
}

int main(void)
{
    check_fifo();
    char manifest[1024];
    snprintf(manifest, sizeof manifest, "%s/badinput/expect.txt", LUMESH_TEST_DIR);
    FILE *f = fopen(manifest, "r");
    CHECK_MSG(f != NULL, "cannot open %s", manifest);
    if (!f) return test_finish("scene_badinput_test");
    char line[1024];
    int cases = 0;
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\r\n")] = '\0';
        if (line[0] == '#' || line[0] == '\0') continue;
        char *fields[5];
        int n = 0;
        for (char *p = strtok(line, "|"); p && n < 5; p = strtok(NULL, "|")) fields[n++] = p;
        CHECK_MSG(n == 5, "malformed manifest line");
        if (n != 5) continue;
        CHECK(strcmp(fields[2], "2") == 0 || strcmp(fields[2], "0") == 0);
        if (strcmp(fields[2], "0") == 0)
            run_accepted(fields[0], fields[3], fields[4]);
        else
            run_case(fields[0], fields[1], fields[3], fields[4]);
        cases++;
    }
    fclose(f);
    CHECK_MSG(cases >= 15, "only %d corpus files", cases);
    return test_finish("scene_badinput_test");
}
