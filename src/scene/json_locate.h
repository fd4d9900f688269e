/* Finds where a value sits in JSON text, for error messages that name line and column.
 * jansson validates the text first; this only walks text that is known to be valid. */
#ifndef FM_JSON_LOCATE_H
#define FM_JSON_LOCATE_H

/* A path into the document: components are object keys, or array indices when key is NULL. */
typedef struct fm_json_step {
    const char *key;
    int index;
} fm_json_step;

/* Line and column (1-based) of the value at path, or of its key when want_key is set and the last
 * step is a key. Returns 0 on success, -1 if the path is not in the text (line/col then 0). */
int fm_json_locate(const char *text, const fm_json_step *path, int depth, int want_key, int *line,
                   int *col);

#endif
