/* resources/scenario.sdlfmu -> the data block of scenario.h.
 *
 * The file is text, one record per line (sdl_fmu/export/scenario_fmu.py writes it): a keyword and its fields,
 * separated by blanks; '#' starts a comment. Real numbers are C99 hexadecimal floats ("0x1.8p+1", what Python's
 * float.hex() writes), read here exactly and without the C library (no locale, the same bits on every platform);
 * whole numbers are decimal. Every field is checked against its range; the first problem makes the whole file
 * refused with "<file>:<line>: <what>" (the FMU then fails to instantiate with that message, never crashes).
 *
 *   sdl-fmu-scenario 1
 *   guid <instantiation token>
 *   source <the SDL file's name>
 *   road <lane width> <lanes right> <lanes left>
 *   es <distance> | es none
 *   last <distance of the last event>
 *   start_lateral <lane 1's centre, + right>
 *   slots <traffic slots>
 *   parameter <name> <start value>                           (the FMU's parameters' start values; 0/1 Booleans)
 *   vehicle <model> <length> <width> <name...>              (the vehicle table rows the A events use)
 *   events <n>
 *   A <line> <distance> <speed> <*> <gap> <lateral> <*> <model> <initial: 0 | 1 <lateral> <*> <speed> <*>
 *     <duration>> <n actions> [<closure s> <where 0/1(F)/2(B)> <lateral> <*> <speed> <*> <duration>] x n
 *     (<*>: 1 relative to the ego's value, else 0; initial: a transition from the spawn, which SDL text cannot give)
 *   BRK <line> <distance> <pedal 0..1> <threshold 0..3> <magnitude>
 *   RSA <line> <distance> <n> [<lane> <value>] x n
 *   ES <line> <distance>
 *   end
 * Events are listed in the order they take effect (by distance, file order breaking ties).
 */
#if defined(__MINGW32__) && !defined(__USE_MINGW_ANSI_STDIO)
#define __USE_MINGW_ANSI_STDIO 1
#endif
#include "scenario.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define MAX_LENGTH 1.0e6     /* m: distances, gaps, lateral positions (the SDL parser's limits) */
#define MAX_SPEED 1.0e3      /* m/s */
#define MAX_DURATION 1.0e6   /* s */
#define MAX_LANE_WIDTH 100.0 /* m */
#define MAX_LANES_PER_SIDE 100
#define MAX_SURFACE_VALUE 1000.0
#define MAX_VEHICLE_SIZE 1000.0
#define MAX_SLOTS 64
#define MAX_EVENTS 2000000
#define MAX_MODEL_NUMBER 1.0e15
#define MAX_NAME 80
#define MAX_GUID 80
#define MAX_SETTINGS (2 * (2 * MAX_LANES_PER_SIDE + 2))
#define MAX_LINE_NUMBER 2147483647.0

typedef struct {
    const char *text, *end, *file;
    const char *next;                  /* where the next line starts */
    const char *cursor, *content_end;  /* the current line's content (comment and trailing blanks cut) */
    int line;
    char *reason;
    size_t reason_size;
    int failed;
} Reader;

static void fail(Reader *r, const char *format, ...) {
    va_list args;
    int n;
    if (r->failed) return;
    r->failed = 1;
    n = snprintf(r->reason, r->reason_size, "%s:%d: ", r->file, r->line);
    if (n < 0 || (size_t)n >= r->reason_size) return;
    va_start(args, format);
    vsnprintf(r->reason + n, r->reason_size - (size_t)n, format, args);
    va_end(args);
}

static int blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

/* A field quoted in a message: at most 40 characters, printable ASCII only (others shown as '?'). */
static const char *quoted(const char *start, size_t length, char *buffer) {
    size_t i, n = length > 40 ? 40 : length;
    for (i = 0; i < n; i++) buffer[i] = start[i] >= 0x20 && start[i] < 0x7f ? start[i] : '?';
    buffer[n] = '\0';
    return buffer;
}

/* The next line with content (comments and blank lines skipped); 0 at the end of the text or on a failure. */
static int next_line(Reader *r) {
    while (!r->failed && r->next < r->end) {
        const char *start = r->next, *p = start, *content;
        while (p < r->end && *p != '\n') {
            if (*p == '\0') {
                r->line++;
                fail(r, "a NUL byte in the text");
                return 0;
            }
            p++;
        }
        r->line++;
        r->next = p < r->end ? p + 1 : p;
        content = start;
        while (content < p && *content != '#') content++;
        while (content > start && blank(content[-1])) content--;
        r->cursor = start;
        while (r->cursor < content && blank(*r->cursor)) r->cursor++;
        r->content_end = content;
        if (r->cursor < content) return 1;
    }
    return 0;
}

/* The next blank-separated field of the line (0: none left). */
static int token(Reader *r, const char **start, size_t *length) {
    const char *p = r->cursor;
    while (p < r->content_end && blank(*p)) p++;
    if (p >= r->content_end) return 0;
    *start = p;
    while (p < r->content_end && !blank(*p)) p++;
    *length = (size_t)(p - *start);
    r->cursor = p;
    return 1;
}

static int field(Reader *r, const char *name, const char **start, size_t *length) {
    if (r->failed) return 0;
    if (!token(r, start, length)) {
        fail(r, "%s: missing", name);
        return 0;
    }
    return 1;
}

static int is_keyword(const char *start, size_t length, const char *keyword) {
    return strlen(keyword) == length && memcmp(start, keyword, length) == 0;
}

static int hex_digit(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* A C99 hexadecimal float, [+-]0x<hex>[.<hex>]p[+-]<decimal>, at most 14 significant hex digits: exact. */
static int parse_hex(const char *s, size_t n, double *value) {
    const char *p = s, *end = s + n;
    unsigned long long mantissa = 0;
    int negative = 0, digits = 0, fraction_digits = 0, seen_point = 0, exponent = 0, exponent_negative = 0;
    int exponent_digits = 0;
    if (p < end && (*p == '+' || *p == '-')) negative = *p++ == '-';
    if (end - p < 3 || p[0] != '0' || (p[1] != 'x' && p[1] != 'X')) return 0;
    p += 2;
    for (; p < end && *p != 'p' && *p != 'P'; p++) {
        int h;
        if (*p == '.') {
            if (seen_point) return 0;
            seen_point = 1;
            continue;
        }
        if ((h = hex_digit(*p)) < 0) return 0;
        if (mantissa == 0 && h == 0) { /* leading zeros do not count */
            if (seen_point) fraction_digits++;
            digits += 0;
            continue;
        }
        if (++digits > 14) return 0;
        mantissa = mantissa * 16 + (unsigned long long)h;
        if (seen_point) fraction_digits++;
    }
    if (p >= end) return 0; /* the binary exponent is required */
    p++;
    if (p < end && (*p == '+' || *p == '-')) exponent_negative = *p++ == '-';
    for (; p < end; p++) {
        if (*p < '0' || *p > '9' || ++exponent_digits > 5) return 0;
        exponent = exponent * 10 + (*p - '0');
    }
    if (exponent_digits == 0) return 0;
    if (exponent_negative) exponent = -exponent;
    *value = ldexp((double)mantissa, exponent - 4 * fraction_digits);
    if (negative) *value = -*value;
    return isfinite(*value);
}

static int read_real(Reader *r, const char *name, double low, double high, double *value) {
    char shown[41];
    const char *start;
    size_t length;
    if (!field(r, name, &start, &length)) return 0;
    if (!parse_hex(start, length, value)) {
        fail(r, "%s: '%s' is not a hexadecimal floating-point number", name, quoted(start, length, shown));
        return 0;
    }
    if (!(*value >= low && *value <= high)) {
        fail(r, "%s: %.17g is outside [%g, %g]", name, *value, low, high);
        return 0;
    }
    return 1;
}

static int read_whole(Reader *r, const char *name, double low, double high, double *value) {
    char shown[41];
    const char *start, *p;
    size_t length;
    double number = 0.0;
    int negative = 0, digits = 0;
    if (!field(r, name, &start, &length)) return 0;
    p = start;
    if (*p == '+' || *p == '-') negative = *p++ == '-';
    for (; p < start + length; p++) {
        if (*p < '0' || *p > '9' || ++digits > 16) {
            fail(r, "%s: '%s' is not a whole number", name, quoted(start, length, shown));
            return 0;
        }
        number = number * 10 + (*p - '0');
    }
    if (digits == 0) {
        fail(r, "%s: '%s' is not a whole number", name, quoted(start, length, shown));
        return 0;
    }
    *value = negative ? -number : number;
    if (!(*value >= low && *value <= high)) {
        fail(r, "%s: %.0f is outside [%.0f, %.0f]", name, *value, low, high);
        return 0;
    }
    return 1;
}

static int line_done(Reader *r) {
    char shown[41];
    const char *start;
    size_t length;
    if (r->failed) return 0;
    if (token(r, &start, &length)) {
        fail(r, "unexpected field '%s'", quoted(start, length, shown));
        return 0;
    }
    return 1;
}

/* A line "<keyword> ..." (the keyword read). */
static int keyword_line(Reader *r, const char *keyword) {
    char shown[41];
    const char *start;
    size_t length;
    if (r->failed) return 0;
    if (!next_line(r)) {
        if (!r->failed) fail(r, "'%s' expected, the file ends (truncated?)", keyword);
        return 0;
    }
    token(r, &start, &length);
    if (!is_keyword(start, length, keyword)) {
        fail(r, "'%s' expected, found '%s'", keyword, quoted(start, length, shown));
        return 0;
    }
    return 1;
}

/* The rest of the line as text (a name), at most `size - 1` characters of printable ASCII. */
static int rest_of_line(Reader *r, const char *name, char *text, size_t size) {
    const char *p = r->cursor;
    size_t n;
    while (p < r->content_end && blank(*p)) p++;
    n = (size_t)(r->content_end - p);
    if (n == 0 || n >= size) {
        fail(r, "%s: %s", name, n == 0 ? "missing" : "too long");
        return 0;
    }
    memcpy(text, p, n);
    text[n] = '\0';
    for (p = text; *p; p++)
        if ((unsigned char)*p < 0x20 || (unsigned char)*p >= 0x7f) {
            fail(r, "%s: not printable ASCII", name);
            return 0;
        }
    r->cursor = r->content_end;
    return 1;
}

/* ---- the whole file ----------------------------------------------------------------------------------------- */

typedef struct {
    double model, length, width;
    char name[MAX_NAME];
} Model;

typedef struct {
    /* pass 1 counts, pass 2 fills `data` (NULL in pass 1) */
    double *data;
    size_t size;                          /* doubles of the data block */
    int n_events, n_vehicles, n_slots, n_surface_lanes;
    double lane_width, lanes_right, lanes_left, es, has_es, last, start_lateral;
    size_t events_size, settings;         /* doubles of the event records, RSA settings in all */
    int lane_settings[LANE_INDEX_SIZE];   /* per lane, its settings */
    int lane_filled[LANE_INDEX_SIZE];     /* pass 2: settings placed so far */
    Model *models;
    int n_models, models_capacity;
    char guid[MAX_GUID];
    char **names;                         /* pass 2: per vehicle, its model's name */
    double *parameters;                   /* N_PARAMETERS start values (the interface's, then the file's) */
    int given[N_PARAMETERS];
} Parsed;

static int find_model(const Parsed *parsed, double number) {
    int i;
    for (i = 0; i < parsed->n_models; i++)
        if (parsed->models[i].model == number) return i;
    return -1;
}

/* Offsets (from the data block's start) of its parts, once the counts are known. */
typedef struct {
    size_t event_offsets, vehicle_events, lane_index, surfaces, settings, events;
} Layout;

static Layout layout_of(const Parsed *parsed) {
    Layout l;
    l.event_offsets = H_COUNT;
    l.vehicle_events = l.event_offsets + (size_t)parsed->n_events;
    l.lane_index = l.vehicle_events + (size_t)parsed->n_vehicles;
    l.surfaces = l.lane_index + LANE_INDEX_SIZE;
    l.settings = l.surfaces + (size_t)parsed->n_surface_lanes * SL_SIZE;
    l.events = l.settings + 2 * parsed->settings;
    return l;
}

/* "parameter <name> <value>": a declared parameter's start value, within its declared range. */
static int read_parameter(Reader *r, Parsed *parsed) {
    char shown[41];
    const char *start;
    size_t length;
    int i;
    double value;
    if (!field(r, "parameter name", &start, &length)) return 0;
    for (i = 0; i < N_SCENARIO_VARIABLES; i++) {
        const ModelVariable *v = &SCENARIO_VARIABLES[i];
        if (v->store != STORE_PARAMETER || !is_keyword(start, length, v->name)) continue;
        if (!read_real(r, v->name, v->kind == KIND_BOOLEAN ? 0.0 : v->min, v->kind == KIND_BOOLEAN ? 1.0 : v->max,
                       &value))
            return 0;
        if (v->kind != KIND_REAL && value != floor(value)) {
            fail(r, "%s: %.17g is not a whole number", v->name, value);
            return 0;
        }
        if (parsed->given[v->index]) {
            fail(r, "%s: given twice", v->name);
            return 0;
        }
        parsed->given[v->index] = 1;
        parsed->parameters[v->index] = value;
        return 1;
    }
    fail(r, "parameter: '%s' is not a parameter of the scenario FMU", quoted(start, length, shown));
    return 0;
}

/* One pass over the text; in pass 2 (parsed->data set) the block is filled at `layout`. */
static int parse_pass(Reader *r, Parsed *parsed, const Layout *layout, void *(*allocate)(size_t, size_t)) {
    char shown[41];
    double value, distance, previous_distance = 0.0, count;
    const char *start;
    size_t length, event_cursor = 0;
    int k, vehicle_count = 0, filling = parsed->data != NULL;
    double *data = parsed->data;
    char text[MAX_NAME > MAX_GUID ? MAX_NAME : MAX_GUID];

    if (keyword_line(r, "sdl-fmu-scenario") && read_whole(r, "format", 1, 1, &value)) line_done(r);
    if (keyword_line(r, "guid") && field(r, "guid", &start, &length)) {
        size_t i;
        if (length >= MAX_GUID) fail(r, "guid: too long");
        for (i = 0; i < length && !r->failed; i++)
            if (!((start[i] >= '0' && start[i] <= '9') || (start[i] >= 'a' && start[i] <= 'z') ||
                  (start[i] >= 'A' && start[i] <= 'Z') || start[i] == '{' || start[i] == '}' || start[i] == '-'))
                fail(r, "guid: not a GUID");
        if (!r->failed) {
            memcpy(parsed->guid, start, length);
            parsed->guid[length] = '\0';
        }
        line_done(r);
    }
    if (keyword_line(r, "source")) rest_of_line(r, "source", text, sizeof(text));
    if (keyword_line(r, "road") && read_real(r, "lane width", 1e-3, MAX_LANE_WIDTH, &parsed->lane_width) &&
        read_whole(r, "lanes right", 1, MAX_LANES_PER_SIDE, &parsed->lanes_right) &&
        read_whole(r, "lanes left", 0, MAX_LANES_PER_SIDE, &parsed->lanes_left))
        line_done(r);
    if (keyword_line(r, "es")) {
        const char *save = r->cursor;
        if (token(r, &start, &length) && is_keyword(start, length, "none")) {
            parsed->has_es = 0.0;
            parsed->es = 0.0;
        } else {
            r->cursor = save;
            parsed->has_es = 1.0;
            read_real(r, "ES distance", 0.0, MAX_LENGTH, &parsed->es);
        }
        line_done(r);
    }
    if (keyword_line(r, "last") && read_real(r, "last distance", 0.0, MAX_LENGTH, &parsed->last)) line_done(r);
    if (keyword_line(r, "start_lateral") &&
        read_real(r, "start lateral", -MAX_LENGTH, MAX_LENGTH, &parsed->start_lateral))
        line_done(r);
    if (keyword_line(r, "slots") && read_whole(r, "slots", 0, MAX_SLOTS, &value)) {
        parsed->n_slots = (int)value;
        line_done(r);
    }

    /* the parameters' start values, the vehicle table, then the events */
    while (!r->failed) {
        if (!next_line(r)) {
            if (!r->failed) fail(r, "'events' expected, the file ends (truncated?)");
            break;
        }
        token(r, &start, &length);
        if (is_keyword(start, length, "events")) break;
        if (is_keyword(start, length, "parameter")) {
            if (read_parameter(r, parsed)) line_done(r);
            continue;
        }
        if (!is_keyword(start, length, "vehicle")) {
            fail(r, "'vehicle' or 'events' expected, found '%s'", quoted(start, length, shown));
            break;
        }
        {
            Model model;
            if (!read_whole(r, "model", 1, MAX_MODEL_NUMBER, &model.model) ||
                !read_real(r, "length", 1e-3, MAX_VEHICLE_SIZE, &model.length) ||
                !read_real(r, "width", 1e-3, MAX_VEHICLE_SIZE, &model.width) ||
                !rest_of_line(r, "name", model.name, sizeof(model.name)))
                break;
            if (filling) continue; /* the table was read in pass 1 */
            if (find_model(parsed, model.model) >= 0) {
                fail(r, "model %.0f is listed twice", model.model);
                break;
            }
            if (parsed->n_models >= parsed->models_capacity) { /* (counted before: cannot happen) */
                fail(r, "more vehicle rows than counted");
                break;
            }
            parsed->models[parsed->n_models++] = model;
        }
    }
    if (r->failed) return 0;
    if (!read_whole(r, "events", 0, MAX_EVENTS, &count) || !line_done(r)) return 0;
    if (!filling) {
        parsed->n_events = (int)count;
    } else {
        data[H_FORMAT] = DATA_FORMAT;
        data[H_N_EVENTS] = parsed->n_events;
        data[H_N_VEHICLES] = parsed->n_vehicles;
        data[H_N_SLOTS] = parsed->n_slots;
        data[H_LANE_WIDTH] = parsed->lane_width;
        data[H_LANES_RIGHT] = parsed->lanes_right;
        data[H_LANES_LEFT] = parsed->lanes_left;
        data[H_HAS_ES] = parsed->has_es;
        data[H_ES_DISTANCE] = parsed->es;
        data[H_LAST_DISTANCE] = parsed->last;
        data[H_START_LATERAL] = parsed->start_lateral;
        data[H_EVENT_OFFSETS] = (double)layout->event_offsets;
        data[H_VEHICLE_EVENTS] = (double)layout->vehicle_events;
        data[H_LANE_INDEX] = (double)layout->lane_index;
        data[H_N_SURFACE_LANES] = parsed->n_surface_lanes;
        data[H_SURFACES] = (double)layout->surfaces;
        data[H_SIZE] = (double)parsed->size;
        {   /* the surface lanes, in lane order, and where each one's starts and values go */
            int lane, index = 0;
            size_t place = layout->settings;
            for (lane = 0; lane < LANE_INDEX_SIZE; lane++) {
                data[layout->lane_index + (size_t)lane] = -1.0;
                if (parsed->lane_settings[lane] == 0) continue;
                data[layout->lane_index + (size_t)lane] = index;
                data[layout->surfaces + (size_t)index * SL_SIZE + SL_LANE] = lane - RIGHT_SHOULDER;
                data[layout->surfaces + (size_t)index * SL_SIZE + SL_COUNT] = parsed->lane_settings[lane];
                data[layout->surfaces + (size_t)index * SL_SIZE + SL_STARTS] = (double)place;
                data[layout->surfaces + (size_t)index * SL_SIZE + SL_VALUES] =
                    (double)(place + (size_t)parsed->lane_settings[lane]);
                place += 2 * (size_t)parsed->lane_settings[lane];
                index++;
            }
        }
    }

    for (k = 0; k < (int)count && !r->failed; k++) {
        double line, code_value = 0.0;
        size_t record = layout ? layout->events + event_cursor : 0;
        if (!next_line(r)) {
            if (!r->failed) fail(r, "event %d of %.0f expected, the file ends (truncated?)", k + 1, count);
            break;
        }
        token(r, &start, &length);
        if (is_keyword(start, length, "A"))
            code_value = CODE_A;
        else if (is_keyword(start, length, "BRK"))
            code_value = CODE_BRK;
        else if (is_keyword(start, length, "RSA"))
            code_value = CODE_RSA;
        else if (is_keyword(start, length, "ES"))
            code_value = CODE_ES;
        else {
            fail(r, "an event (A, BRK, RSA or ES) expected, found '%s'", quoted(start, length, shown));
            break;
        }
        if (!read_whole(r, "line", 1, MAX_LINE_NUMBER, &line) ||
            !read_real(r, "distance", 0.0, MAX_LENGTH, &distance))
            break;
        if (distance < previous_distance) {
            fail(r, "the events are not in distance order");
            break;
        }
        previous_distance = distance;
        if (filling) {
            data[layout->event_offsets + (size_t)k] = (double)record;
            data[record + E_CODE] = code_value;
            data[record + E_LINE] = line;
            data[record + E_DISTANCE] = distance;
        }
        if (code_value == CODE_A) {
            double a[A_SIZE];
            int model, j;
            memset(a, 0, sizeof(a));
            if (!read_real(r, "speed", -MAX_SPEED, MAX_SPEED, &a[A_SPEED]) ||
                !read_whole(r, "speed relative", 0, 1, &a[A_SPEED_RELATIVE]) ||
                !read_real(r, "gap", -MAX_LENGTH, MAX_LENGTH, &a[A_GAP]) ||
                !read_real(r, "lateral", -MAX_LENGTH, MAX_LENGTH, &a[A_LATERAL]) ||
                !read_whole(r, "lateral relative", 0, 1, &a[A_LATERAL_RELATIVE]) ||
                !read_whole(r, "model", 1, MAX_MODEL_NUMBER, &a[A_MODEL]) ||
                !read_whole(r, "initial", 0, 1, &a[A_INITIAL]))
                break;
            if (a[A_INITIAL] != 0.0 &&
                (!read_real(r, "initial lateral", -MAX_LENGTH, MAX_LENGTH, &a[A_INITIAL_LATERAL]) ||
                 !read_whole(r, "initial lateral relative", 0, 1, &a[A_INITIAL_LATERAL_RELATIVE]) ||
                 !read_real(r, "initial speed", -MAX_SPEED, MAX_SPEED, &a[A_INITIAL_SPEED]) ||
                 !read_whole(r, "initial speed relative", 0, 1, &a[A_INITIAL_SPEED_RELATIVE]) ||
                 !read_real(r, "initial duration", 0.0, MAX_DURATION, &a[A_INITIAL_DURATION])))
                break;
            if (!read_whole(r, "actions", 0, MAX_ACTIONS, &a[A_N_ACTIONS])) break;
            if ((model = find_model(parsed, a[A_MODEL])) < 0) {
                fail(r, "model %.0f is not in the vehicle table", a[A_MODEL]);
                break;
            }
            a[A_LENGTH] = parsed->models[model].length;
            a[A_WIDTH] = parsed->models[model].width;
            for (j = 0; j < (int)a[A_N_ACTIONS] && !r->failed; j++) {
                double *act = a + A_ACTIONS + (size_t)j * ACT_SIZE;
                if (read_real(r, "closure time", -MAX_DURATION, MAX_DURATION, &act[ACT_SECONDS]) &&
                    act[ACT_SECONDS] == 0.0)
                    fail(r, "closure time: 0");
                if (!r->failed && read_whole(r, "where", 0, 2, &act[ACT_WHERE]) &&
                    read_real(r, "action lateral", -MAX_LENGTH, MAX_LENGTH, &act[ACT_LATERAL]) &&
                    read_whole(r, "action lateral relative", 0, 1, &act[ACT_LATERAL_RELATIVE]) &&
                    read_real(r, "action speed", -MAX_SPEED, MAX_SPEED, &act[ACT_SPEED]) &&
                    read_whole(r, "action speed relative", 0, 1, &act[ACT_SPEED_RELATIVE]))
                    read_real(r, "transition time", 0.0, MAX_DURATION, &act[ACT_DURATION]);
            }
            if (r->failed || !line_done(r)) break;
            if (filling) {
                memcpy(data + record + E_PAYLOAD, a + E_PAYLOAD, sizeof(double) * (A_SIZE - E_PAYLOAD));
                data[layout->vehicle_events + (size_t)vehicle_count] = k;
                parsed->names[vehicle_count] = NULL;
                {
                    size_t n = strlen(parsed->models[model].name) + 1;
                    char *copy = (char *)allocate(n, 1);
                    if (copy) memcpy(copy, parsed->models[model].name, n);
                    parsed->names[vehicle_count] = copy;
                }
            }
            vehicle_count++;
            event_cursor += A_SIZE;
        } else if (code_value == CODE_BRK) {
            double pedal, threshold, magnitude;
            if (!read_real(r, "pedal", 0.0, 1.0, &pedal) || !read_whole(r, "threshold", 0, 3, &threshold) ||
                !read_real(r, "magnitude", 0.0, MAX_LENGTH, &magnitude) || !line_done(r))
                break;
            if (filling) {
                data[record + BRK_PEDAL] = pedal;
                data[record + BRK_THRESHOLD] = threshold;
                data[record + BRK_MAGNITUDE] = magnitude;
            }
            event_cursor += BRK_SIZE;
        } else if (code_value == CODE_RSA) {
            double n, lane, surface;
            int j;
            if (!read_whole(r, "settings", 1, MAX_SETTINGS, &n)) break;
            if (filling) data[record + RSA_COUNT] = n;
            for (j = 0; j < (int)n && !r->failed; j++) {
                int index;
                if (!read_whole(r, "lane", LEFT_SHOULDER, RIGHT_SHOULDER, &lane) ||
                    !read_real(r, "value", 0.0, MAX_SURFACE_VALUE, &surface))
                    break;
                if (lane == 0.0) {
                    fail(r, "lane: 0 is not a lane");
                    break;
                }
                index = (int)lane + RIGHT_SHOULDER;
                if (!filling) {
                    parsed->lane_settings[index]++;
                    parsed->settings++;
                } else {
                    size_t surface_record =
                        layout->surfaces + (size_t)data[layout->lane_index + (size_t)index] * SL_SIZE;
                    size_t place = (size_t)parsed->lane_filled[index]++;
                    data[(size_t)data[surface_record + SL_STARTS] + place] = distance;
                    data[(size_t)data[surface_record + SL_VALUES] + place] = surface;
                    data[record + RSA_SETTINGS + 2 * (size_t)j] = lane;
                    data[record + RSA_SETTINGS + 2 * (size_t)j + 1] = surface;
                }
            }
            if (r->failed || !line_done(r)) break;
            event_cursor += RSA_SETTINGS + 2 * (size_t)n;
        } else {
            if (!line_done(r)) break;
            if (parsed->has_es == 0.0 || distance != parsed->es) {
                fail(r, "ES at a distance the 'es' line does not give");
                break;
            }
            event_cursor += ES_SIZE;
        }
    }
    if (r->failed) return 0;
    if (keyword_line(r, "end") && line_done(r) && next_line(r)) fail(r, "text after 'end'");
    if (r->failed) return 0;
    if (!filling) {
        int lane;
        parsed->n_vehicles = vehicle_count;
        parsed->events_size = event_cursor;
        for (lane = 0; lane < LANE_INDEX_SIZE; lane++)
            if (parsed->lane_settings[lane]) parsed->n_surface_lanes++;
    }
    return 1;
}

void scenario_free_names(char **names, int count, void (*release)(void *)) {
    int i;
    if (!names) return;
    for (i = 0; i < count; i++)
        if (names[i]) release(names[i]);
    release(names);
}

double *scenario_parse(const char *text, size_t length, const char *file, void *(*allocate)(size_t, size_t),
                       void (*release)(void *), size_t *size, char **guid, char ***names, double *parameters,
                       char *reason, size_t reason_size) {
    Parsed *parsed = (Parsed *)allocate(1, sizeof(Parsed));
    Reader reader;
    Layout layout;
    double *data = NULL;
    if (!parsed) {
        snprintf(reason, reason_size, "%s: out of memory", file);
        return NULL;
    }
    memset(&reader, 0, sizeof(reader));
    reader.text = reader.next = text;
    reader.end = text + length;
    reader.file = file;
    reader.reason = reason;
    reader.reason_size = reason_size;
    *names = NULL;
    *guid = NULL;
    {   /* the interface's start values, which the file's parameter lines override */
        int i;
        for (i = 0; i < N_SCENARIO_VARIABLES; i++)
            if (SCENARIO_VARIABLES[i].store == STORE_PARAMETER)
                parameters[SCENARIO_VARIABLES[i].index] = SCENARIO_STARTS[i];
        parsed->parameters = parameters;
    }
    {   /* the vehicle rows, counted for the table (at most one per line) */
        const char *p = text, *end = text + length;
        int rows = 0;
        while (p < end) {
            while (p < end && (*p == ' ' || *p == '\t')) p++;
            if ((size_t)(end - p) > 8 && memcmp(p, "vehicle", 7) == 0 && (p[7] == ' ' || p[7] == '\t')) rows++;
            while (p < end && *p != '\n') p++;
            p++;
        }
        parsed->models_capacity = rows;
        parsed->models = (Model *)allocate((size_t)rows + 1, sizeof(Model));
        if (!parsed->models) {
            snprintf(reason, reason_size, "%s: out of memory", file);
            release(parsed);
            return NULL;
        }
    }
    if (parse_pass(&reader, parsed, NULL, allocate)) {
        layout = layout_of(parsed);
        parsed->size = layout.events + parsed->events_size;
        data = (double *)allocate(parsed->size + 1, sizeof(double));
        parsed->names = (char **)allocate((size_t)parsed->n_vehicles + 1, sizeof(char *));
        *guid = (char *)allocate(strlen(parsed->guid) + 1, 1);
        if (!data || !parsed->names || !*guid) {
            snprintf(reason, reason_size, "%s: out of memory", file);
        } else {
            memcpy(*guid, parsed->guid, strlen(parsed->guid) + 1);
            memset(&reader, 0, sizeof(reader));
            memset(parsed->given, 0, sizeof(parsed->given));
            reader.text = reader.next = text;
            reader.end = text + length;
            reader.file = file;
            reader.reason = reason;
            reader.reason_size = reason_size;
            parsed->data = data;
            if (parse_pass(&reader, parsed, &layout, allocate)) {
                *size = parsed->size;
                *names = parsed->names;
                release(parsed->models);
                release(parsed);
                return data;
            }
        }
    }
    if (parsed->names) scenario_free_names(parsed->names, parsed->n_vehicles, release);
    if (data) release(data);
    if (*guid) release(*guid);
    *guid = NULL;
    release(parsed->models);
    release(parsed);
    return NULL;
}
