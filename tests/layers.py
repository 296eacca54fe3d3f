#!/usr/bin/env python3
"""layers — keeps the layer order of the source tree (docs/architecture.md).

Reads every `#include "..."` of every C, C++ and header file under src/, mesh/ and
sampling/ and fails, naming the file, the line, the include and the rule broken,
when:
  folder    a source file lies outside the folders of the layer table below;
  root      a project include does not name its file from the repository root
            ("mesh/cache/cache.h"), or names a file that does not exist;
  order     a file includes a header of a higher layer;
  internal  a *_internal.h is included from outside its own folder;
  gl        GL is used (the GL loader or a platform's header included, the
            GladGLContext table named, a gl->Call made) outside src/gpu/,
            src/render/, src/view/, the GL sampler (sampling/samp_gl*) and the
            imperfect shadow maps (sampling/ref_ism.c).

usage: layers.py ROOT          check the tree at ROOT; exit 0 when it keeps every rule
       layers.py --self-test   check trees made to break each rule once (and one that
                               breaks none): exit 0 when each is reported as it should be
"""
import os
import re
import sys
import tempfile

# (folder, layer), lowest layer first. A file belongs to the longest folder that
# contains it: mesh/cache/x.c is layer 3, mesh/x.c layer 1.
LAYERS = [
    ("src/base", 0),
    ("src/scene", 1),
    ("src/image", 1),
    ("src/gpu", 1),
    ("mesh", 1),
    ("sampling", 2),
    ("mesh/cache", 3),
    ("src/render", 4),
    ("src/view", 5),
    ("src/cli", 5),
]
SCANNED = ("src", "mesh", "sampling")
SOURCE_EXT = (".c", ".h", ".cpp", ".hpp")
GL_ALLOWED = ("src/gpu/", "src/render/", "src/view/")
GL_ALLOWED_FILES = re.compile(r"^sampling/(samp_gl[a-z_]*|ref_ism)\.(c|h)$")

INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')
GL_USE = [
    (re.compile(r"^\s*#\s*include\s*<(glad/|EGL/|GL/|GLFW/)"), "includes a GL header"),
    (re.compile(r"\bGladGLContext\b"), "names GladGLContext"),
    (re.compile(r"\bgl->[A-Z]\w*\s*\("), "calls GL"),
]


def folder_of(rel):
    """The layer folder of a repository-relative path, or None."""
    best = None
    for folder, layer in LAYERS:
        d = os.path.dirname(rel)
        if d == folder and (best is None or len(folder) > len(best[0])):
            best = (folder, layer)
    return best


def strip_comments(line, in_block):
    """The line without /* */ and // comments, and whether a block comment is open after it."""
    out, i = [], 0
    while i < len(line):
        if in_block:
            j = line.find("*/", i)
            if j < 0:
                return "".join(out), True
            i, in_block = j + 2, False
        elif line.startswith("/*", i):
            in_block, i = True, i + 2
        elif line.startswith("//", i):
            break
        else:
            out.append(line[i])
            i += 1
    return "".join(out), in_block


def check(root):
    """Every rule broken under root, as 'file:line: rule: what' strings."""
    problems = []
    files = []
    for top in SCANNED:
        for d, _, names in os.walk(os.path.join(root, top)):
            for n in sorted(names):
                if n.endswith(SOURCE_EXT):
                    files.append(os.path.relpath(os.path.join(d, n), root).replace(os.sep, "/"))
    for rel in sorted(files):
        home = folder_of(rel)
        if home is None:
            problems.append(f"{rel}:1: folder: {os.path.dirname(rel)}/ is no layer's folder "
                            f"(layers: {', '.join(f for f, _ in LAYERS)})")
            continue
        gl_ok = rel.startswith(GL_ALLOWED) or GL_ALLOWED_FILES.match(rel)
        in_block = False
        with open(os.path.join(root, rel), encoding="utf-8") as f:
            for no, raw in enumerate(f, 1):
                m = INCLUDE.match(raw)
                line, in_block = strip_comments(raw, in_block)
                if not gl_ok:
                    for pat, what in GL_USE:
                        if pat.search(line):
                            problems.append(f"{rel}:{no}: gl: {what} outside src/gpu/, src/render/, "
                                            f"src/view/, sampling/samp_gl* and sampling/ref_ism.c: {raw.strip()}")
                if not m or not INCLUDE.match(line):
                    continue
                inc = m.group(1)
                if not inc.startswith(tuple(t + "/" for t in SCANNED)) or ".." in inc.split("/"):
                    problems.append(f'{rel}:{no}: root: #include "{inc}" must name its folder from the '
                                    f'repository root (e.g. "mesh/cache/cache.h")')
                    continue
                if not os.path.isfile(os.path.join(root, inc)):
                    problems.append(f'{rel}:{no}: root: #include "{inc}": no such file')
                    continue
                there = folder_of(inc)
                if there is None:
                    continue  # reported as a folder problem of that file
                if there[1] > home[1]:
                    problems.append(f'{rel}:{no}: order: #include "{inc}": {home[0]}/ is layer {home[1]}, '
                                    f'{there[0]}/ is layer {there[1]}; include only your own layer or lower')
                if inc.endswith("_internal.h") and os.path.dirname(inc) != os.path.dirname(rel):
                    problems.append(f'{rel}:{no}: internal: #include "{inc}": a *_internal.h is for '
                                    f'{os.path.dirname(inc)}/ only')
    return problems, len(files)


def self_test():
    """Each rule, broken once in a small tree, is reported with its name and file."""
    def make(tree):
        d = tempfile.mkdtemp(prefix="layers-")
        for rel, text in tree.items():
            os.makedirs(os.path.join(d, os.path.dirname(rel)), exist_ok=True)
            with open(os.path.join(d, rel), "w", encoding="utf-8") as f:
                f.write(text)
        return d

    good = {
        "src/base/util.h": "/* util */\n",
        "src/scene/scene.h": '#include "src/base/util.h"\n#include "mesh/geomesh.h"\n',
        "mesh/geomesh.h": '#include "src/base/util.h"\n',
        "mesh/cache/cache.h": '#include "sampling/samp.h"\n',
        "mesh/cache/cache_internal.h": '#include "mesh/cache/cache.h"\n',
        "mesh/cache/cache.c": '#include "mesh/cache/cache_internal.h"\n/* gl->Clear( in a comment */\n',
        "sampling/samp.h": '#include "src/scene/scene.h"\n',
        "sampling/samp_gl.c": "#include <glad/gl.h>\nvoid f(const GladGLContext *gl) { gl->Flush(); }\n",
        "src/render/rend.c": '#include <glad/gl.h>\n#include "mesh/cache/cache.h"\n',
        "src/cli/main.c": '#include "src/render/rend.h"\n',
        "src/render/rend.h": '#include "src/base/util.h"\n',
    }
    cases = [
        ("none", {}, None),
        ("folder", {"src/misc/x.c": "\n"}, "src/misc/x.c:1: folder:"),
        ("root (bare name)", {"src/cli/x.c": '#include "util.h"\n'}, "src/cli/x.c:1: root:"),
        ("root (missing)", {"src/cli/x.c": '#include "src/base/nothing.h"\n'}, "src/cli/x.c:1: root:"),
        ("order", {"sampling/x.c": '#include "mesh/cache/cache.h"\n'}, "sampling/x.c:1: order:"),
        ("order (front end into the cache's folder)", {"mesh/x.c": '\n#include "src/render/rend.h"\n'},
         "mesh/x.c:2: order:"),
        ("internal", {"src/render/x.c": '#include "mesh/cache/cache_internal.h"\n'}, "src/render/x.c:1: internal:"),
        ("gl (include)", {"mesh/cache/x.c": "#include <glad/gl.h>\n"}, "mesh/cache/x.c:1: gl:"),
        ("gl (call)", {"src/cli/x.c": "void f(void) {\n  gl->DrawArrays(0, 0, 3);\n}\n"}, "src/cli/x.c:2: gl:"),
    ]
    failed = 0
    for name, extra, want in cases:
        tree = dict(good)
        tree.update(extra)
        problems, _ = check(make(tree))
        ok = (not problems) if want is None else (len(problems) == 1 and problems[0].startswith(want))
        print(f"  {'ok ' if ok else 'BAD'} {name}: {problems if problems else 'no problems'}")
        failed += not ok
    return failed


def main(argv):
    if len(argv) == 2 and argv[1] == "--self-test":
        failed = self_test()
        print(f"layers self-test: {failed} case(s) not reported as they should be")
        return 1 if failed else 0
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    problems, n = check(argv[1])
    for p in problems:
        print(p)
    print(f"layers: {n} files under {', '.join(s + '/' for s in SCANNED)}; {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
