/* scene_xml.c — an XML file into a small element tree, through expat.
 *
 * Mitsuba's scene format is elements and attributes only (text content carries
 * nothing), so the tree keeps just those, with each element's line for
 * messages. Expat does not read external entities unless asked (we do not ask)
 * and, from 2.4, refuses entity expansion that amplifies the input (billion
 * laughs); the depth is capped here, so a deep file cannot exhaust the stack of
 * the recursive free and walks.
 */
#include <expat.h>
#include <stdlib.h>
#include <string.h>

#include "src/scene/scene_mitsuba_internal.h"

enum { MTS_MAX_BYTES = 64 << 20, MTS_MAX_DEPTH = 256 };

typedef struct xml_state {
    XML_Parser parser;
    mts_node *root, *current;
    int depth;
    int failed;          /* 1: out of memory, 2: too deep */
} xml_state;

static char *dup_string(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d) memcpy(d, s, n);
    return d;
}

void mts_free(mts_node *n)
{
    while (n) {
        mts_free(n->child);
        mts_node *next = n->next;
        free(n->tag);
        for (char **a = n->attrs; a && *a; ++a) free(*a);
        free(n->attrs);
        free(n);
        n = next;
    }
}

static mts_node *new_node(const char *tag, const char **attrs, int line)
{
    mts_node *n = calloc(1, sizeof *n);
    if (!n) return NULL;
    size_t count = 0;
    while (attrs[count]) count++;
    n->tag = dup_string(tag);
    n->attrs = calloc(count + 1, sizeof *n->attrs);
    n->line = line;
    if (!n->tag || !n->attrs) {
        mts_free(n);
        return NULL;
    }
    for (size_t i = 0; i < count; ++i)
        if (!(n->attrs[i] = dup_string(attrs[i]))) {
            mts_free(n);
            return NULL;
        }
    return n;
}

static void XMLCALL on_start(void *user, const XML_Char *tag, const XML_Char **attrs)
{
    xml_state *st = user;
    if (st->failed) return;
    if (++st->depth > MTS_MAX_DEPTH) {
        st->failed = 2;
        XML_StopParser(st->parser, XML_FALSE);
        return;
    }
    mts_node *n = new_node(tag, attrs, (int)XML_GetCurrentLineNumber(st->parser));
    if (!n) {
        st->failed = 1;
        XML_StopParser(st->parser, XML_FALSE);
        return;
    }
    if (!st->current) {
        st->root = n;
    } else {
        n->parent = st->current;
        mts_node **tail = &st->current->child;
        while (*tail) tail = &(*tail)->next; /* siblings are few: a walk is fine */
        *tail = n;
    }
    st->current = n;
}

static void XMLCALL on_end(void *user, const XML_Char *tag)
{
    (void)tag;
    xml_state *st = user;
    if (st->failed) return;
    st->depth--;
    if (st->current) st->current = st->current->parent;
}

lm_result mts_parse_file(const char *path, mts_node **out, lm_error *err)
{
    *out = NULL;
    char *text = NULL;
    size_t size = 0;
    lm_result r = lm_read_file(path, MTS_MAX_BYTES, &text, &size, err);
    if (r != LM_OK) return r;
    if (size == 0) {
        free(text);
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: the file is empty", path);
    }
    xml_state st;
    memset(&st, 0, sizeof st);
    st.parser = XML_ParserCreate(NULL);
    if (!st.parser) {
        free(text);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory (XML parser)", path);
    }
    XML_SetUserData(st.parser, &st);
    XML_SetElementHandler(st.parser, on_start, on_end);
    enum XML_Status status = XML_Parse(st.parser, text, (int)size, XML_TRUE);
    if (st.failed == 1) {
        r = lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory reading the XML", path);
    } else if (st.failed == 2) {
        r = lm_fail(err, LM_ERR_BAD_INPUT, "%s:%lu: elements nested more than %d deep", path,
                    (unsigned long)XML_GetCurrentLineNumber(st.parser), MTS_MAX_DEPTH);
    } else if (status != XML_STATUS_OK) {
        r = lm_fail(err, LM_ERR_BAD_INPUT, "%s:%lu:%lu: not well-formed XML: %s", path,
                    (unsigned long)XML_GetCurrentLineNumber(st.parser),
                    (unsigned long)XML_GetCurrentColumnNumber(st.parser) + 1,
                    XML_ErrorString(XML_GetErrorCode(st.parser)));
    } else if (!st.root) {
        r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: no XML element in the file", path);
    }
    XML_ParserFree(st.parser);
    free(text);
    if (r != LM_OK) {
        mts_free(st.root);
        return r;
    }
    *out = st.root;
    return LM_OK;
}

const char *mts_attr(const mts_node *n, const char *name)
{
    for (char **a = n->attrs; a && a[0] && a[1]; a += 2)
        if (strcmp(a[0], name) == 0) return a[1];
    return NULL;
}
