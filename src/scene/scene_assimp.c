/* scene_assimp.c — mesh files through Assimp's C API.
 *
 * Assimp reads OBJ+MTL completely (Kd, Ks, Ns, Ke, d, illum), PLY, OFF, STL,
 * glTF 2.0 and more, with quads, negative indices and CRLF handled by a
 * maintained parser (docs/scene-model.md says why Assimp rather than our own).
 * All file access goes through an aiFileIO over vfs_read, so the built-in scene
 * loads from memory exactly as a disk scene does, and so we can tell the user
 * which referenced file (an MTL, a glTF buffer) could not be opened.
 *
 * This file only translates: node transforms, materials, triangles. Cleaning
 * happens in scene_build.c. The import runs in a child process (scene_isolate.c:
 * Assimp crashes, loops and leaks on some malformed files), after the guards of
 * scene_guard.c. Assimp keeps its last error in a process-wide string, so loads
 * must not run concurrently (they do not: loading happens on one thread).
 */
#include <assimp/cfileio.h>
#include <assimp/cimport.h>
#include <assimp/ObjMaterial.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vfs.h"
#include "src/scene/scene_internal.h"

enum { MAX_MESH_FILE_BYTES = 1 << 30, MAX_MISSING = 8, MTL_MIN_BYTES = 16 };

/* ---- aiFileIO over vfs_read -------------------------------------------- */

typedef struct io_context {
    const char *main_path;
    char *main_data;            /* pre-read main file, handed to Assimp on open */
    size_t main_size;
    char missing[MAX_MISSING][256];
    int missing_count;
    int main_is_obj;            /* every other file opened is a material library */
    char empty[MAX_MISSING][256]; /* material libraries that define no material */
    int empty_count;
    uint32_t mtl_dropped;       /* texture statements before a newmtl, commented out (scene_guard_mtl) */
} io_context;

typedef struct mem_file {
    char *data;
    size_t size, pos;
    int owned;                  /* free data on close (not the main file's buffer) */
} mem_file;

static size_t io_read(struct aiFile *f, char *buf, size_t size, size_t count)
{
    mem_file *m = (mem_file *)(void *)f->UserData;
    if (size == 0 || m->pos >= m->size) return 0;
    size_t n = (m->size - m->pos) / size;
    if (n > count) n = count;
    memcpy(buf, m->data + m->pos, n * size);
    m->pos += n * size;
    return n;
}

static size_t io_write(struct aiFile *f, const char *buf, size_t size, size_t count)
{
    (void)f, (void)buf, (void)size, (void)count;
    return 0; /* read-only */
}

static size_t io_tell(struct aiFile *f) { return ((mem_file *)(void *)f->UserData)->pos; }
static size_t io_size(struct aiFile *f) { return ((mem_file *)(void *)f->UserData)->size; }
static void io_flush(struct aiFile *f) { (void)f; }

static enum aiReturn io_seek(struct aiFile *f, size_t offset, enum aiOrigin origin)
{
    mem_file *m = (mem_file *)(void *)f->UserData;
    size_t base = origin == aiOrigin_SET ? 0 : origin == aiOrigin_CUR ? m->pos : m->size;
    if (offset > m->size - base) return aiReturn_FAILURE;
    m->pos = base + offset;
    return aiReturn_SUCCESS;
}

/* Whether a material library holds a `newmtl` statement anywhere. */
static int defines_material(const char *data, size_t size)
{
    for (size_t i = 0; i + 6 <= size; ++i)
        if (data[i] == 'n' && memcmp(data + i, "newmtl", 6) == 0) return 1;
    return 0;
}

static struct aiFile *io_open(struct aiFileIO *io, const char *path, const char *mode)
{
    io_context *ctx = (io_context *)(void *)io->UserData;
    if (!mode || mode[0] != 'r') return NULL;
    char *data = NULL;
    size_t size = 0;
    int owned = 1;
    if (strcmp(path, ctx->main_path) == 0) {
        data = ctx->main_data;
        size = ctx->main_size;
        owned = 0;
    } else if (vfs_read(path, MAX_MESH_FILE_BYTES, &data, &size, NULL) != LM_OK) {
        if (ctx->missing_count < MAX_MISSING)
            lm_strlcpy(ctx->missing[ctx->missing_count++], path, sizeof ctx->missing[0]);
        return NULL;
    } else if (ctx->main_is_obj) {
        /* An OBJ reader opens nothing but material libraries, whatever their names:
         * each goes through the MTL guard (the OBJ itself did before the import). */
        ctx->mtl_dropped += scene_guard_mtl(data, size);
        if (!defines_material(data, size) && ctx->empty_count < MAX_MISSING)
            lm_strlcpy(ctx->empty[ctx->empty_count++], path, sizeof ctx->empty[0]);
        /* Assimp refuses a library of 1 to 7 bytes ("File is too small") and with it
         * the whole OBJ; blank lines change nothing in an MTL. */
        if (size < MTL_MIN_BYTES) {
            char *padded = realloc(data, MTL_MIN_BYTES + 1);
            if (!padded) {
                free(data);
                return NULL;
            }
            memset(padded + size, '\n', MTL_MIN_BYTES - size);
            padded[MTL_MIN_BYTES] = '\0';
            data = padded;
            size = MTL_MIN_BYTES;
        }
    }
    struct aiFile *f = calloc(1, sizeof *f);
    mem_file *m = calloc(1, sizeof *m);
    if (!f || !m) {
        free(f);
        free(m);
        if (owned) free(data);
        return NULL;
    }
    m->data = data;
    m->size = size;
    m->owned = owned;
    f->ReadProc = io_read;
    f->WriteProc = io_write;
    f->TellProc = io_tell;
    f->FileSizeProc = io_size;
    f->SeekProc = io_seek;
    f->FlushProc = io_flush;
    f->UserData = (aiUserData)(void *)m;
    return f;
}

static void io_close(struct aiFileIO *io, struct aiFile *f)
{
    (void)io;
    if (!f) return;
    mem_file *m = (mem_file *)(void *)f->UserData;
    if (m->owned) free(m->data);
    free(m);
    free(f);
}

/* ---- materials ----------------------------------------------------------- */

static void read_color(const struct aiMaterial *am, const char *key, unsigned type, unsigned idx,
                       float out[3])
{
    struct aiColor4D c;
    if (aiGetMaterialColor(am, key, type, idx, &c) == aiReturn_SUCCESS) {
        out[0] = c.r;
        out[1] = c.g;
        out[2] = c.b;
    }
}

static scene_material translate_material(const struct aiMaterial *am)
{
    struct aiString name;
    name.length = 0;
    name.data[0] = '\0';
    aiGetMaterialString(am, AI_MATKEY_NAME, &name);
    scene_material m = scene_material_default(name.data);
    if (name.length == 0 || strcmp(name.data, AI_DEFAULT_MATERIAL_NAME) == 0) {
        /* Assimp's stand-in when the file has no material: named "DefaultMaterial"
         * (PLY, STL, OBJ without mtllib) or nameless (OFF, glTF's spare one). */
        lm_strlcpy(m.name, "default", sizeof m.name);
        m.notes |= SCENE_MATNOTE_DEFAULT;
        return m;
    }
    read_color(am, AI_MATKEY_COLOR_DIFFUSE, m.kd);
    read_color(am, AI_MATKEY_COLOR_SPECULAR, m.ks);
    read_color(am, AI_MATKEY_COLOR_EMISSIVE, m.le);
    float f;
    if (aiGetMaterialFloatArray(am, AI_MATKEY_SHININESS, &f, NULL) == aiReturn_SUCCESS) m.n = f;
    float strength;
    if (aiGetMaterialFloatArray(am, AI_MATKEY_EMISSIVE_INTENSITY, &strength, NULL) ==
            aiReturn_SUCCESS &&
        strength > 0.0f)
        for (int c = 0; c < 3; ++c) m.le[c] *= strength;
    /* Opacity: OBJ `d`. `Tr` is transparency (1 - d); we model no transparency
     * either way, so a `Tr 0` some loaders misread as "fully transparent" has no
     * effect here. Only a real d < 1 is reported. */
    if (aiGetMaterialFloatArray(am, AI_MATKEY_OPACITY, &f, NULL) == aiReturn_SUCCESS && f < 0.999f &&
        f > 0.0f)
        m.notes |= SCENE_MATNOTE_TRANSPARENCY_IGNORED;
    int illum;
    if (aiGetMaterialIntegerArray(am, AI_MATKEY_OBJ_ILLUM, &illum, NULL) == aiReturn_SUCCESS &&
        illum >= 3 && illum <= 9)
        m.notes |= SCENE_MATNOTE_REFRACTION_AS_PHONG;
    return m;
}

/* ---- geometry ------------------------------------------------------------ */

typedef struct import_state {
    scene_builder *b;
    const struct aiScene *ai;
    const char *path;
    uint32_t *mat_index;        /* builder material per Assimp material */
    uint32_t *part_index;       /* builder part per Assimp mesh, UINT32_MAX until used */
    int32_t material_override;
    uint32_t skipped_non_triangles;
    uint32_t bad_indices;
} import_state;

static lm_result emit_mesh(import_state *st, unsigned mesh_i, const double *m, lm_error *err)
{
    const struct aiMesh *mesh = st->ai->mMeshes[mesh_i];
    if (st->part_index[mesh_i] == UINT32_MAX) {
        const char *name = mesh->mName.length ? mesh->mName.data : "mesh";
        lm_result r = scene_builder_add_part(st->b, name, st->path, &st->part_index[mesh_i], err);
        if (r != LM_OK) return r;
    }
    uint32_t material = st->material_override >= 0 ? (uint32_t)st->material_override
                        : mesh->mMaterialIndex < st->ai->mNumMaterials
                            ? st->mat_index[mesh->mMaterialIndex]
                            : UINT32_MAX;
    double cof[9];
    double det = scene_mat4_normal_matrix(m, cof);
    double nsign = det < 0.0 ? -1.0 : 1.0; /* cofactor = det·M^-T: keep the direction */
    int mirror = det < 0.0;
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
        const struct aiFace *face = &mesh->mFaces[f];
        if (face->mNumIndices != 3) {
            st->skipped_non_triangles++;
            continue;
        }
        double p[9];
        float n[9];
        int has_n = mesh->mNormals != NULL, ok = 1;
        for (int k = 0; k < 3; ++k) {
            unsigned vi = face->mIndices[mirror && k ? 3 - k : k];
            if (vi >= mesh->mNumVertices) {
                ok = 0;
                break;
            }
            const struct aiVector3D *vp = &mesh->mVertices[vi];
            const double local[3] = {vp->x, vp->y, vp->z};
            scene_mat4_point(m, local, p + 3 * k);
            if (has_n) {
                const struct aiVector3D *v = &mesh->mNormals[vi];
                for (int i = 0; i < 3; ++i)
                    n[3 * k + i] = (float)(nsign * (cof[3 * i] * v->x + cof[3 * i + 1] * v->y +
                                                    cof[3 * i + 2] * v->z));
            }
        }
        if (!ok) {
            st->bad_indices++;
            continue;
        }
        lm_result r = scene_builder_add_triangle(st->b, p, has_n ? n : NULL, material,
                                                 st->part_index[mesh_i], err);
        if (r != LM_OK) return r;
    }
    return LM_OK;
}

static lm_result walk(import_state *st, const struct aiNode *node, const double *parent, int depth,
                      lm_error *err)
{
    if (depth > 256)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: node hierarchy deeper than 256 levels", st->path);
    const struct aiMatrix4x4 *t = &node->mTransformation;
    double local[16] = {t->a1, t->a2, t->a3, t->a4, t->b1, t->b2, t->b3, t->b4,
                        t->c1, t->c2, t->c3, t->c4, t->d1, t->d2, t->d3, t->d4};
    double m[16];
    scene_mat4_mul(parent, local, m);
    for (unsigned i = 0; i < node->mNumMeshes; ++i) {
        if (node->mMeshes[i] >= st->ai->mNumMeshes) continue;
        lm_result r = emit_mesh(st, node->mMeshes[i], m, err);
        if (r != LM_OK) return r;
    }
    for (unsigned i = 0; i < node->mNumChildren; ++i) {
        lm_result r = walk(st, node->mChildren[i], m, depth + 1, err);
        if (r != LM_OK) return r;
    }
    return LM_OK;
}

/* Text formats must not contain NUL bytes; a binary blob named .obj is garbage. */
static int looks_binary_text_format(const char *ext, const char *data, size_t size)
{
    if (strcmp(ext, "obj") && strcmp(ext, "off") && strcmp(ext, "mtl") && strcmp(ext, "gltf"))
        return 0;
    return memchr(data, '\0', size) != NULL;
}

typedef struct import_args {
    const char *path;
    const double *transform;
} import_args;

static lm_result import_mesh_file(scene_builder *b, void *user, int32_t material_override, lm_error *err);

lm_result scene_import_mesh_file(scene_builder *b, const char *path, const double *transform,
                                 int32_t material_override, lm_error *err)
{
    import_args args = {path, transform};
    return scene_isolate(b, path, material_override, import_mesh_file, &args, err);
}

/* The import itself (in the child process scene_isolate made). */
static lm_result import_mesh_file(scene_builder *b, void *user, int32_t material_override, lm_error *err)
{
    const char *path = ((const import_args *)user)->path;
    const double *transform = ((const import_args *)user)->transform;
    char ext[16], dotext[20];
    lm_path_ext(path, ext, sizeof ext);
    snprintf(dotext, sizeof dotext, ".%s", ext);
    if (!ext[0] || !aiIsExtensionSupported(dotext))
        return lm_fail(err, LM_ERR_BAD_INPUT,
                       "%s: unsupported file type '%s' (use .obj, .ply, .off, .stl, .gltf/.glb or a "
                       ".json scene description)",
                       path, ext[0] ? dotext : "(no extension)");

    io_context ctx;
    memset(&ctx, 0, sizeof ctx);
    ctx.main_path = path;
    ctx.main_is_obj = strcmp(ext, "obj") == 0;
    lm_result r = vfs_read(path, MAX_MESH_FILE_BYTES, &ctx.main_data, &ctx.main_size, err);
    if (r != LM_OK) return r;
    if (ctx.main_size == 0) {
        free(ctx.main_data);
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: the file is empty", path);
    }
    if (looks_binary_text_format(ext, ctx.main_data, ctx.main_size)) {
        free(ctx.main_data);
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: not a text %s file (it contains binary data)",
                       path, ext);
    }

    const char *malformed = NULL;
    int malformed_line = 0;
    if (strcmp(ext, "ply") == 0) malformed = scene_guard_ply(ctx.main_data, ctx.main_size, &malformed_line);
    if (strcmp(ext, "gltf") == 0 || strcmp(ext, "glb") == 0)
        malformed = scene_guard_gltf(ctx.main_data, ctx.main_size);
    if (malformed) {
        if (malformed_line)
            r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read %s file: line %d: %s", path, ext, malformed_line,
                        malformed);
        else
            r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read %s file: %s", path, ext, malformed);
        free(ctx.main_data);
        return r;
    }
    if (ctx.main_is_obj) ctx.mtl_dropped += scene_guard_mtl(ctx.main_data, ctx.main_size);
    scene_number_scan numbers;
    scene_guard_numbers(ext, ctx.main_data, ctx.main_size, &numbers);
    b->numbers_too_large += numbers.overflow + numbers.out_of_range;
    if (numbers.overflow)
        scene_builder_note(b, "%s: %u number%s too large for a float (read as Inf: the triangles using them are "
                              "dropped)",
                           path, numbers.overflow, numbers.overflow == 1 ? " is" : "s are");
    if (numbers.underflow)
        scene_builder_note(b, "%s: %u non-zero number%s below float's smallest normal value (1.2e-38), read as 0",
                           path, numbers.underflow, numbers.underflow == 1 ? "" : "s");
    if (numbers.out_of_range)
        scene_builder_note(b, "%s: %u number%s beyond %.2g (the triangles using them are dropped)", path,
                           numbers.out_of_range, numbers.out_of_range == 1 ? "" : "s", SCENE_COORD_MAX);

    struct aiFileIO io = {io_open, io_close, (aiUserData)(void *)&ctx};
    /* Validation runs first and must stay: Assimp's triangulation aborts the process
     * on the inconsistent structures some broken files produce. */
    unsigned flags = aiProcess_ValidateDataStructure | aiProcess_Triangulate;
    const struct aiScene *ai = aiImportFileEx(path, flags, &io);
    if (!ai) {
        const char *why = aiGetErrorString();
        r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read %s file: %s", path, ext,
                    why && why[0] ? why : "unknown Assimp error");
        free(ctx.main_data);
        return r;
    }

    import_state st;
    memset(&st, 0, sizeof st);
    st.b = b;
    st.ai = ai;
    st.path = path;
    st.material_override = material_override;
    st.mat_index = calloc(ai->mNumMaterials + 1, sizeof *st.mat_index);
    st.part_index = malloc((ai->mNumMeshes + 1) * sizeof *st.part_index);
    if (!st.mat_index || !st.part_index) {
        r = lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", path);
        goto done;
    }
    for (unsigned i = 0; i < ai->mNumMeshes; ++i) st.part_index[i] = UINT32_MAX;
    if (material_override < 0)
        for (unsigned i = 0; i < ai->mNumMaterials; ++i) {
            scene_material m = translate_material(ai->mMaterials[i]);
            r = scene_builder_add_material(b, &m, &st.mat_index[i], err);
            if (r != LM_OK) goto done;
        }
    if (ai->mFlags & AI_SCENE_FLAGS_INCOMPLETE || !ai->mRootNode) {
        r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: the file holds no complete scene (no meshes)", path);
        goto done;
    }
    {
        double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, root[16];
        if (transform)
            for (int i = 0; i < 16; ++i) root[i] = transform[i];
        else
            memcpy(root, identity, sizeof root);
        r = walk(&st, ai->mRootNode, root, 0, err);
        if (r != LM_OK) goto done;
    }
    if (st.skipped_non_triangles)
        scene_builder_note(b, "%s: ignored %u point/line primitives (only triangles are rendered)",
                           path, st.skipped_non_triangles);
    if (st.bad_indices) {
        r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: %u faces refer to vertices that do not exist", path,
                    st.bad_indices);
        goto done;
    }
    if (ctx.mtl_dropped)
        scene_builder_note(b, "%s: %u texture statement%s before the first newmtl of a material library: ignored", path,
                           ctx.mtl_dropped, ctx.mtl_dropped == 1 ? "" : "s");
    for (int i = 0; i < ctx.empty_count; ++i)
        scene_builder_note(b, "%s: its material library '%s' defines no material (no newmtl): default materials used",
                           path, ctx.empty[i]);
    for (int i = 0; i < ctx.missing_count; ++i)
        scene_builder_note(b, "%s: could not open '%s' that it refers to; default materials used",
                           path, ctx.missing[i]);
done:
    free(st.mat_index);
    free(st.part_index);
    aiReleaseImport(ai);
    free(ctx.main_data);
    return r;
}
