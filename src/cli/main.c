/* main.c — `lumesh`, git-style: lumesh COMMAND [ARGS]. */
#define _POSIX_C_SOURCE 200809L /* setenv, execv */
#include <malloc.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "src/cli/cli.h"

/* The sampler options of render, converge and view. */
#define SAMPLER_HELP                                                                          \
    "  --sampler NAME      irradiance sampler: gl, embree, or auto (default: embree, then the\n" \
    "                      cheaper of the two measured once the cache has converged; GL's\n"  \
    "                      costs are kept in ~/.cache/lumesh, and a run where GL cannot win\n" \
    "                      measures nothing; LUMESH_CACHE_DIR= switches that off)\n"           \
    "  --gl NAME           GL platform of the gl sampler: egl (default) or osmesa\n"       \
    "  --bounces K|auto    diffuse bounces shown, 1..32, or auto (default): until the rest would\n" \
    "                      change the picture by at most a quarter of the JND where it is seen\n" \
    "  --exposure E        stops of the picture's exposure (default: the scene's); the cache\n"   \
    "                      refines for the colours shown at it\n"

static const app_command commands[] = {
    {"info", "print what a scene holds: triangles, materials, lights, cameras, what was dropped",
     "usage: lumesh info [SCENE]\n"
     "\n"
     "Loads SCENE and prints its triangles, materials, lights (area, radiance, power,\n"
     "facing direction), cameras, bounds, topology, and what loading dropped or\n"
     "approximated. SCENE is a mesh file (.obj .ply .off .stl .gltf .glb) or a .json\n"
     "scene description; without SCENE the built-in Cornell box is used.\n"
     "\n"
     "exit codes: 0 ok, 1 usage, 2 bad input, 3 runtime failure\n",
     cmd_info},
    {"render", "progressive multi-mesh render to an image (headless)",
     "usage: lumesh render [SCENE] -o OUT.png|OUT.exr [--seconds T | --samples N [--deterministic]]\n"
     "                     [--width W --height H] [--supersample S] [--accumulate K] [--camera NAME]\n"
     "                     [--stats STATS.json] [--sampler gl|embree|auto] [--gl egl|osmesa]\n"
     "                     [--bounces K|auto] [--debug-meshes DIR] [--components LIST]\n"
     "                     [--residual on|off] [--exposure E]\n"
     "\n"
     "Refines the multi-mesh cache of SCENE (headless: EGL, or --gl osmesa) until it\n"
     "has converged at its JND (nothing left to test), T seconds have passed (it\n"
     "refines on to lower JNDs meanwhile) or N leaves are tested, then draws it and\n"
     "writes a tone-mapped PNG or a linear EXR. With --seconds, the time left once the\n"
     "cache has finished path-traces its residual, which corrects the picture where it\n"
     "shows it wrong. On a terminal it shows its progress.\n"
     "Without SCENE the built-in Cornell box.\n"
     "\n"
     "  -o, --output FILE   image to write (.png or .exr)\n"
     "  --seconds T         stop refining after T seconds (default: when converged)\n"
     "  --samples N         stop refining after N leaf tests\n"
     "  --deterministic     with --samples: the same N gives the same image, bit for bit\n"
     "                      (the sampler is embree unless --sampler gl is given: auto\n"
     "                      calibrates by timing, which no run can reproduce)\n"
     "  --width W, --height H   image size (default: the camera's)\n"
     "  --supersample S     S x S samples a pixel, box-filtered (default 3; 1 = pixel centres)\n"
     "  --accumulate K      average K x K draws with the samples moved inside a sub-pixel:\n"
     "                      (K*S) x (K*S) samples a pixel without the memory (default 3, 1..8)\n"
     "  --camera NAME       one of the scene's cameras (default: the first)\n"
     "  --stats FILE        write per-mesh sample statistics as JSON (docs/stats.md)\n"
     "  --debug-meshes DIR  write DIR/MESH-leaves.png (leaf wireframe) and DIR/MESH-samples.png\n"
     "                      (sample positions) over the image, MESH = light0.., direct,\n"
     "                      indirect, specular; hidden parts are left out\n"
     "  --components LIST   draw only these terms of the composite, comma-separated: direct\n"
     "                      (kd*L_dd), indirect (kd*E_i/pi), specular (ks*(L_ds + L_is): the lights\n"
     "                      and the room in glossy materials), emission (Le);\n"
     "                      default all (the terms add up to the whole image)\n"
     "  --residual on|off   with --seconds: path-trace the residual beside the refining\n"
     "                      cache (on the cycles it leaves) and with every core once it has\n"
     "                      finished (default on; the picture then tends to the truth)\n"
     SAMPLER_HELP,
     cmd_render},
    {"reference", "ray-traced ground truth (Embree path tracer)",
     "usage: lumesh reference [SCENE] -o OUT.exr (--spp N | --seconds T)\n"
     "                        [--transport model|full] [--bounces K] [--glossy indirect|direct]\n"
     "                        [--seed S] [--threads N] [--add PREVIOUS.exr]\n"
     "                        [--camera NAME] [--width W --height H]\n"
     "\n"
     "Progressive, multi-threaded path tracing of SCENE (built-in Cornell box if left out).\n"
     "\n"
     "  -o, --output FILE   EXR to write: channels R,G,B, stderr.R/G/B (standard error of\n"
     "                      each pixel's mean) and samples\n"
     "  --spp N             N samples per pixel (same seed and N: the same image)\n"
     "  --seconds T         sample for T seconds\n"
     "  --transport model   exactly the previewer's light transport (default): emission,\n"
     "                      direct diffuse, exact direct Phong specular, K diffuse bounces\n"
     "  --transport full    unbiased path tracing of all bounces (MIS, Russian roulette)\n"
     "  --bounces K         diffuse bounces of the model transport (default 1; 0 = direct)\n"
     "  --glossy indirect   glossy materials of the model transport reflect the lights and\n"
     "                      the bounces' source, as the previewer's (default)\n"
     "  --glossy direct     ...the lights only (the paper's model; `converge` then has the\n"
     "                      previewer do the same)\n"
     "  --seed S            random seed (default 0)\n"
     "  --threads N         worker threads (default: every core)\n"
     "  --add PREVIOUS.exr  pool this run's samples with a reference of the same scene, size\n"
     "                      and transport made with other seeds (checked: the file lists its\n"
     "                      seeds); OUT holds both, weighted by their samples (OUT may be\n"
     "                      PREVIOUS: it is read before sampling starts)\n"
     "  --camera NAME       one of the scene's cameras (default: the first)\n"
     "  --width W, --height H   image size (default: the camera's)\n"
     "\n"
     "Prints the mean relative standard error (mean over pixels of SE(Y)/sqrt(Y^2+0.01)).\n"
     "Ctrl-C stops and still writes the complete samples; a second Ctrl-C quits at once.\n",
     cmd_reference},
    {"compare", "measure the error between two images",
     "usage: lumesh compare A.exr B.exr [--json] [--heatmap OUT.png] [--exposure E]\n"
     "\n"
     "Prints RMSE, relMSE, PSNR, maximum error and tone-mapped CIELAB ΔE of A against\n"
     "the reference B: linear images of the same size, normally EXR (other formats\n"
     "are compared as stored: a PNG's values stay sRGB-encoded). The channels named\n"
     "R, G, B are compared (others such as stderr.R are ignored); without those\n"
     "names the first three, and a one-channel image as grey. Pixels with a NaN or\n"
     "infinite R, G or B in either image are left out and counted.\n"
     "\n"
     "  RMSE, relMSE    over pixels and R, G, B of the linear values;\n"
     "                  relMSE = mean of (A-B)^2 / (B^2 + 0.01)\n"
     "  PSNR            20 log10(1 / RMSE) dB (peak 1.0); inf for identical images\n"
     "  ΔE              CIE76 after the display tone mapping; mean, 99th percentile\n"
     "                  (linear interpolation between ranks) and maximum\n"
     "  OIIO RMSE/PSNR  OpenImageIO's own ImageBufAlgo::compare of the same\n"
     "                  channels, as a check (its PSNR peak is max(1, largest value))\n"
     "\n"
     "  --json          print one JSON object instead (an infinite PSNR is \"inf\")\n"
     "  --heatmap FILE  write per-pixel ΔE as an 8-bit PNG: viridis from ΔE 0\n"
     "                  (dark purple) to 10 and above (yellow); magenta where a\n"
     "                  pixel was left out\n"
     "  --exposure E    stops applied before tone mapping for ΔE (default 0)\n"
     "\n"
     "exit codes: 0 ok, 1 usage, 2 bad input (missing or unreadable file, sizes\n"
     "differ), 3 runtime failure\n",
     cmd_compare},
    {"converge", "scripted convergence run: error against time",
     "usage: lumesh converge [SCENE] --reference REF.exr --seconds T --out DIR\n"
     "                       [--snapshots 0.1,0.2,0.5,1,...] [--methods cache,vpl,bdir,...]\n"
     "                       [--vs-path-tracer] [--single-mesh] [--vpl-paths N] [--vpl-per-sample M]\n"
     "                       [--vpl-clamp F|none] [--camera NAME] [--stats STATS.json] [--supersample S] [--accumulate K]\n"
     "                       [--seed S] [--sampler gl|embree|auto] [--gl egl|osmesa]\n"
     "                       [--bounces K|auto] [--transport model|full] [--residual on|off]\n"
     "                       [--exposure E]\n"
     "\n"
     "Renders SCENE progressively at REF's size for T seconds, counted from the scene\n"
     "loaded. At each snapshot time it draws what the previewer shows, writes it to\n"
     "DIR (EXR and PNG) and compares it with REF (every metric of lumesh compare).\n"
     "Writes DIR/convergence.csv, DIR/convergence.json and DIR/convergence.png\n"
     "(relMSE and mean dE against time, log-log). Ctrl-C stops and still writes what\n"
     "was measured.\n"
     "\n"
     "  --reference REF     linear reference image (lumesh reference); the path tracer follows\n"
     "                      its transport, and without --bounces the previewer shows its\n"
     "                      bounce count (model K) or chooses (full: auto)\n"
     "  --transport T       model or full: the reference's transport where its file does not\n"
     "                      say (default: what it says; else model with one bounce)\n"
     "  --seconds T         length of the run; the last snapshot is at T\n"
     "  --out DIR           output directory (created if missing)\n"
     "  --snapshots LIST    snapshot times in seconds (default 0.1,0.2,0.5,1,2,5,10,... below T)\n"
     "  --methods LIST      what to measure, each for the same times on the same axes, the\n"
     "                      cache first, each with the machine to itself: cache (the previewer),\n"
     "                      vpl (instant radiosity: virtual point lights traced from the lights,\n"
     "                      Embree shadow rays, the same transport; docs/peers.md), bdir\n"
     "                      (bidirectional instant radiosity: VPLs resampled by what the\n"
     "                      camera sees), vpl-ism and bdir-ism (the same with imperfect shadow\n"
     "                      maps made on GL, --gl, instead of shadow rays: biased, cheaper\n"
     "                      joins), path-tracer (the Embree path tracer); default cache\n"
     "  --vs-path-tracer    short for --methods cache,path-tracer\n"
     "  --vpl-paths N       vpl: light paths traced a pass; bdir: VPLs kept a pass, of 8x as\n"
     "                      many light paths (default 1024)\n"
     "  --vpl-per-sample M  vpl, bdir: VPLs a pixel sample joins (default 16)\n"
     "  --vpl-clamp F|none  vpl, bdir: distances to a VPL below F times the scene's diagonal count\n"
     "                      as that (default 0.03: bias near VPLs, no splotches; none: unbiased)\n"
     "  --single-mesh       ablation: one combined radiance mesh instead of the multi-mesh cache\n"
     "  --camera NAME       one of the scene's cameras (default: the first)\n"
     "  --stats FILE        write the final per-mesh statistics as JSON (docs/stats.md)\n"
     "  --supersample S     S x S samples a pixel in the measured images, box-filtered like the\n"
     "                      reference (default 3; the first image is drawn at 1, as a viewer)\n"
     "  --accumulate K      once the cache has converged at its JND, a snapshot is drawn K x K\n"
     "                      times with the samples moved inside a sub-pixel and averaged, as a\n"
     "                      resting view accumulates (default 3; 1 = off); its row's time is\n"
     "                      when that image is complete\n"
     "  --seed S            the path tracer's seed (default 1; keep it different from the\n"
     "                      reference's, whose default is 0, or the two are correlated)\n"
     "  --residual on|off   path-trace the cache's residual (the reference's transport)\n"
     "                      beside the refining cache (on the cycles it leaves) and with\n"
     "                      every core once it has finished, and correct each snapshot's\n"
     "                      picture by it (default on)\n"
     SAMPLER_HELP,
     cmd_converge},
    {"view", "interactive window that sharpens while the camera is idle",
     "usage: lumesh view [SCENE] [--camera NAME] [--width W --height H] [--script FILE]\n"
     "                   [--stats STATS.json] [--max-fps F] [--sampler gl|embree|auto] [--gl egl|osmesa]\n"
     "                   [--bounces K|auto] [--residual on|off] [--indirect cache|vpl|bdir|...]\n"
     "                   [--exposure E]\n"
     "\n"
     "Opens a window on SCENE (default 1280x720); lighting refines in the background\n"
     "and the image sharpens while you look. Once refinement has nothing left to do\n"
     "(or is paused), a still view is corrected by path samples and keeps converging\n"
     "(--residual off: it stops where the cache stopped).\n"
     "  left drag: orbit about the target   middle or shift+left drag: pan   wheel: zoom\n"
     "  right drag: look around   W/A/S/D, Space/Ctrl (or PgUp/PgDn): fly\n"
     "  F: frame everything   C: the scene's next camera\n"
     "  P: pause/resume refinement   +/-: exposure   F12: screenshot (lumesh-view-N.png and .exr)\n"
     "  L: select the next light   ] / [: its power x2 / x0.5   K: its colour (no new light samples)\n"
     "  1/2/3/4: show/hide direct diffuse, direct specular, indirect, emission\n"
     "  O: overlay the next mesh (direct, indirect, specular, each light, off)   V: wireframe/samples\n"
     "  B: bounces (auto, 1, 2, 3, 4, 8; no new light samples)\n"
     "  I: the picture at rest from the cache, VPLs, BDIR, or either with shadow maps (--indirect)\n"
     "  R: reload the scene from its file   H: help in the HUD\n"
     "  Esc/Q: quit\n"
     "\n"
     "  --script FILE       run commands, one per line, then quit: wait SECONDS, frames N,\n"
     "                      orbit DX DY (degrees), zoom FACTOR, pan DX DY (view heights),\n"
     "                      fly FORWARD RIGHT UP (scene units), look DX DY (degrees),\n"
     "                      camera N, screenshot PATH.png|PATH.exr, window-shot PATH.png,\n"
     "                      light INDEX SCALE, light-color INDEX R G B, resize W H,\n"
     "                      minimise, restore,\n"
     "                      next-snapshot SECONDS, peer-picture SECONDS, peer-preview SECONDS,\n"
     "                      key escape|q|p|plus|minus|f12|f|c|l|bracketright|bracketleft|1|2|3|4|h|o|v|r|k|b|i,\n"
     "                      quit; prints a line per screenshot\n"
     "  --stats FILE        write the last snapshot's statistics as JSON at exit (docs/stats.md)\n"
     "  --max-fps F         frame rate cap (default 60; 0: unpaced)\n"
     "  --indirect M        what shows a still view: cache (default), vpl (instant radiosity),\n"
     "                      bdir (its bidirectional resampling), or vpl-ism / bdir-ism (the\n"
     "                      same with imperfect shadow maps on GL, --gl), rendered beside the\n"
     "                      cache and shown from their first complete pass; the cache's\n"
     "                      picture while moving (I cycles them)\n"
     "\n"
     SAMPLER_HELP,
     cmd_view},
};

enum { COMMAND_COUNT = sizeof commands / sizeof commands[0] };

static void print_help(FILE *f)
{
    fprintf(f,
            "lumesh %s — progressive global-illumination previewer (multi-mesh caching)\n"
            "\n"
            "usage: lumesh COMMAND [ARGS]   (lumesh COMMAND --help for each)\n"
            "\n"
            "commands:\n",
            LUMESH_VERSION_STRING);
    for (int i = 0; i < COMMAND_COUNT; ++i)
        fprintf(f, "  %-10s %s\n", commands[i].name, commands[i].summary);
    fprintf(f,
            "\n"
            "SCENE is a mesh file (.obj .ply .off .stl .gltf .glb) or a .json scene\n"
            "description; commands use the built-in Cornell box when it is left out.\n"
            "\n"
            "options: --help, --version\n"
            "exit codes: 0 ok, 1 usage, 2 bad input, 3 runtime failure\n");
}

/* Big blocks in transparent huge pages: glibc's glibc.malloc.hugetlb=1 tunable
 * has malloc advise the kernel (madvise MADV_HUGEPAGE) for the blocks it maps.
 * On the machine these targets are measured on a 4 KiB page fault costs ~10 µs
 * (a paravirtualised guest): `view`'s renderer at 1280×720 (about 70 MB of
 * llvmpipe targets, zeroed as they are made) took 0.17-0.20 s of its first
 * image faulting them in (docs/viewer.md, "Huge pages"). A tunable is read
 * only when a program starts, so lumesh starts itself once more with it (execv
 * keeps the process id; ~20 ms). Not with a sanitizer (its own allocator), not
 * where the kernel has huge pages off, not when GLIBC_TUNABLES already names
 * the tunable (the user's choice, or this start's), and not with
 * LUMESH_HUGE_PAGES=0. If the start fails, this one goes on as it is. */
static void restart_with_huge_pages(char **argv)
{
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    (void)argv;
#else
    const char *off = getenv("LUMESH_HUGE_PAGES");
    if (off && strcmp(off, "0") == 0) return;
    const char *tunables = getenv("GLIBC_TUNABLES");
    if (tunables && strstr(tunables, "glibc.malloc.hugetlb")) return;
    FILE *f = fopen("/sys/kernel/mm/transparent_hugepage/enabled", "r");
    if (!f) return;
    char mode[128] = "";
    int got = fgets(mode, sizeof mode, f) != NULL;
    fclose(f);
    if (!got || strstr(mode, "[never]")) return;
    char value[1024];
    int n = snprintf(value, sizeof value, "%s%sglibc.malloc.hugetlb=1", tunables ? tunables : "",
                     tunables && tunables[0] ? ":" : "");
    if (n < 0 || (size_t)n >= sizeof value || setenv("GLIBC_TUNABLES", value, 1) != 0) return;
    fflush(NULL);
    execv("/proc/self/exe", argv);
    /* Not started: go on without (the variable now names the tunable: no loop). */
#endif
}

int main(int argc, char **argv)
{
    restart_with_huge_pages(argv);
    /* One malloc arena for every thread. glibc makes up to 8 per core, one per
     * thread that allocates (the refinement worker, Embree's and llvmpipe's
     * threads), each keeping its freed memory: two instead cut the 116k-triangle
     * box's peak by 39 MB (docs/memory.md). One, because the huge pages asked for
     * above reach the main arena's heap and mapped blocks but not a second
     * arena's heap: the worker's small blocks there were faulted in 4 KiB at a
     * time, 26,000 faults before the 116k box's first snapshot against 13,400
     * in the main arena, and its first image came at 0.65-0.69 s against
     * 0.51-0.53 s (docs/cache.md, "The worker's memory in huge pages"); peaks
     * and refinement times the same. Before any thread starts; the
     * MALLOC_ARENA_MAX variable, when set, decides instead. */
    if (!getenv("MALLOC_ARENA_MAX")) mallopt(M_ARENA_MAX, 1);
    /* Blocks of 1 MiB and more mapped on their own and given back when freed.
     * glibc's default threshold climbs to the largest block freed so far (up to
     * 32 MiB), after which a big scene's many 1-30 MB arrays (grown by doubling,
     * rebuilt each round) come from the heap, whose freed middle is never given
     * back: the 116k-triangle box's `render --samples 1` peaked at 460 or 558 MB
     * from run to run, at 454 every time with this (docs/memory.md, "Fixed mmap
     * threshold"); no slower. MALLOC_MMAP_THRESHOLD_, when set, decides instead. */
    if (!getenv("MALLOC_MMAP_THRESHOLD_")) mallopt(M_MMAP_THRESHOLD, 1 << 20);
    if (argc < 2) {
        print_help(stderr);
        return APP_EXIT_USAGE;
    }
    const char *name = argv[1];
    if (app_is_help(name) || strcmp(name, "help") == 0) {
        print_help(stdout);
        return APP_EXIT_OK;
    }
    if (strcmp(name, "--version") == 0 || strcmp(name, "version") == 0) {
        printf("lumesh %s\n", LUMESH_VERSION_STRING);
        return APP_EXIT_OK;
    }
    for (int i = 0; i < COMMAND_COUNT; ++i)
        if (strcmp(name, commands[i].name) == 0)
            return commands[i].run(&commands[i], argc - 1, argv + 1);
    fprintf(stderr, "lumesh: '%s' is not a command. See 'lumesh --help'.\n", name);
    return APP_EXIT_USAGE;
}
