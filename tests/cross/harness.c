/* A minimal FMI importer for the cross-platform tests (scripts/test-cross.sh): loads the
 * FMU's library from an unzipped archive the way an importer does, runs one scenario
 * through the FMI 2.0 or FMI 3.0 Co-Simulation C API and prints the outputs at every
 * communication point, one line each, with 17 significant digits.
 *
 * usage: harness LIBRARY fmi2|fmi3 TOKEN RESOURCES STEPS STEP_SIZE OUTPUTS [SET]...
 *   TOKEN      the guid / instantiationToken of modelDescription.xml
 *   RESOURCES  resourceLocation (FMI 2, a file: URI) or resourcePath (FMI 3)
 *   OUTPUTS    comma-separated value references of Float64 outputs
 *   SET        rVR=VALUE  real before initialisation    iVR=VALUE  enumeration before
 *              RVR=VALUE  real at t = 0, after initialisation (a step input)
 * Exit status 0 when every call returned OK. Builds with any C99 compiler: gcc, mingw,
 * zig cc. Only the FMI types the calls need are declared here. */
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *symbol(void *lib, const char *name) {
    return (void *)GetProcAddress((HMODULE)lib, name);
}
#else
#include <dlfcn.h>
static void *open_library(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *symbol(void *lib, const char *name) { return dlsym(lib, name); }
#endif

#define MAX_VALUES 32

typedef unsigned int vr_t;
static vr_t out_vrs[MAX_VALUES];
static size_t n_out;
static void *lib;

static void *need(const char *name) {
    void *f = symbol(lib, name);
    if (!f) {
        fprintf(stderr, "harness: the library exports no %s\n", name);
        exit(2);
    }
    return f;
}

static void check(int status, const char *call) {
    if (status != 0) {
        fprintf(stderr, "harness: %s returned status %d\n", call, status);
        exit(1);
    }
}

/* ---- FMI 2.0 --------------------------------------------------------------------- */
typedef void (*fmi2Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    fmi2Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void *stepFinished;
    void *componentEnvironment;
} fmi2CallbackFunctions;

static void fmi2_log(void *env, const char *instance, int status, const char *category,
                     const char *message, ...) {
    va_list args;
    (void)env;
    fprintf(stderr, "[%s %d %s] ", instance, status, category);
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

/* ---- FMI 3.0 --------------------------------------------------------------------- */
static void fmi3_log(void *env, int status, const char *category, const char *message) {
    (void)env;
    fprintf(stderr, "[%d %s] %s\n", status, category, message);
}

struct setting {
    char kind; /* 'r', 'i' before initialisation, 'R' after */
    vr_t vr;
    double value;
};

static void print_point(double t, const double *values) {
    size_t k;
    printf("%.17g", t);
    for (k = 0; k < n_out; k++) printf(" %.17g", values[k]);
    printf("\n");
}

static void run_fmi2(const char *token, const char *resources, int steps, double h,
                     const struct setting *s, int n_set) {
    typedef void *(*Instantiate)(const char *, int, const char *, const char *,
                                 const fmi2CallbackFunctions *, int, int);
    typedef int (*Setup)(void *, int, double, double, int, double);
    typedef int (*Call)(void *);
    typedef int (*SetReal)(void *, const vr_t *, size_t, const double *);
    typedef int (*SetInteger)(void *, const vr_t *, size_t, const int *);
    typedef int (*GetReal)(void *, const vr_t *, size_t, double *);
    typedef int (*DoStep)(void *, double, double, int);
    typedef void (*Free)(void *);
    static const fmi2CallbackFunctions callbacks = {fmi2_log, calloc, free, NULL, NULL};
    SetReal set_real = (SetReal)need("fmi2SetReal");
    SetInteger set_integer = (SetInteger)need("fmi2SetInteger");
    GetReal get_real = (GetReal)need("fmi2GetReal");
    DoStep do_step = (DoStep)need("fmi2DoStep");
    double values[MAX_VALUES];
    int i, k;
    void *c = ((Instantiate)need("fmi2Instantiate"))("harness", 1 /* fmi2CoSimulation */,
                                                     token, resources, &callbacks, 0, 0);
    if (!c) check(3, "fmi2Instantiate");
    check(((Setup)need("fmi2SetupExperiment"))(c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment");
    for (k = 0; k < n_set; k++) {
        int as_int = (int)s[k].value;
        if (s[k].kind == 'r') check(set_real(c, &s[k].vr, 1, &s[k].value), "fmi2SetReal");
        if (s[k].kind == 'i') check(set_integer(c, &s[k].vr, 1, &as_int), "fmi2SetInteger");
    }
    check(((Call)need("fmi2EnterInitializationMode"))(c), "fmi2EnterInitializationMode");
    check(((Call)need("fmi2ExitInitializationMode"))(c), "fmi2ExitInitializationMode");
    for (k = 0; k < n_set; k++)
        if (s[k].kind == 'R') check(set_real(c, &s[k].vr, 1, &s[k].value), "fmi2SetReal");
    check(get_real(c, out_vrs, n_out, values), "fmi2GetReal");
    print_point(0.0, values);
    for (i = 0; i < steps; i++) {
        check(do_step(c, i * h, h, 1), "fmi2DoStep");
        check(get_real(c, out_vrs, n_out, values), "fmi2GetReal");
        print_point((i + 1) * h, values);
    }
    check(((Call)need("fmi2Terminate"))(c), "fmi2Terminate");
    ((Free)need("fmi2FreeInstance"))(c);
}

static void run_fmi3(const char *token, const char *resources, int steps, double h,
                     const struct setting *s, int n_set) {
    /* fmi3Boolean is C99 bool */
    typedef void *(*Instantiate)(const char *, const char *, const char *, bool, bool, bool,
                                 bool, const vr_t *, size_t, void *,
                                 void (*)(void *, int, const char *, const char *), void *);
    typedef int (*Enter)(void *, bool, double, double, bool, double);
    typedef int (*Call)(void *);
    typedef int (*SetFloat64)(void *, const vr_t *, size_t, const double *, size_t);
    typedef int (*SetInt64)(void *, const vr_t *, size_t, const long long *, size_t);
    typedef int (*GetFloat64)(void *, const vr_t *, size_t, double *, size_t);
    typedef int (*DoStep)(void *, double, double, bool, bool *, bool *, bool *, double *);
    typedef void (*Free)(void *);
    SetFloat64 set_float = (SetFloat64)need("fmi3SetFloat64");
    SetInt64 set_int = (SetInt64)need("fmi3SetInt64");
    GetFloat64 get_float = (GetFloat64)need("fmi3GetFloat64");
    DoStep do_step = (DoStep)need("fmi3DoStep");
    double values[MAX_VALUES], last_time;
    bool event, terminate, early;
    int i, k;
    void *c = ((Instantiate)need("fmi3InstantiateCoSimulation"))(
        "harness", token, resources, false, false, false, false, NULL, 0, NULL, fmi3_log, NULL);
    if (!c) check(3, "fmi3InstantiateCoSimulation");
    for (k = 0; k < n_set; k++) {
        long long as_int = (long long)s[k].value;
        if (s[k].kind == 'r') check(set_float(c, &s[k].vr, 1, &s[k].value, 1), "fmi3SetFloat64");
        if (s[k].kind == 'i') check(set_int(c, &s[k].vr, 1, &as_int, 1), "fmi3SetInt64");
    }
    check(((Enter)need("fmi3EnterInitializationMode"))(c, false, 0.0, 0.0, false, 0.0),
          "fmi3EnterInitializationMode");
    check(((Call)need("fmi3ExitInitializationMode"))(c), "fmi3ExitInitializationMode");
    for (k = 0; k < n_set; k++)
        if (s[k].kind == 'R') check(set_float(c, &s[k].vr, 1, &s[k].value, 1), "fmi3SetFloat64");
    check(get_float(c, out_vrs, n_out, values, n_out), "fmi3GetFloat64");
    print_point(0.0, values);
    for (i = 0; i < steps; i++) {
        check(do_step(c, i * h, h, true, &event, &terminate, &early, &last_time), "fmi3DoStep");
        check(get_float(c, out_vrs, n_out, values, n_out), "fmi3GetFloat64");
        print_point((i + 1) * h, values);
    }
    check(((Call)need("fmi3Terminate"))(c), "fmi3Terminate");
    ((Free)need("fmi3FreeInstance"))(c);
}

int main(int argc, char **argv) {
    struct setting settings[MAX_VALUES];
    int n_set = 0, steps, k;
    double h;
    char *list, *item;
    if (argc < 8) {
        fprintf(stderr, "usage: %s LIBRARY fmi2|fmi3 TOKEN RESOURCES STEPS STEP_SIZE "
                        "OUTPUTS [SET]...\n", argv[0]);
        return 2;
    }
    lib = open_library(argv[1]);
    if (!lib) {
        fprintf(stderr, "harness: cannot load %s\n", argv[1]);
        return 2;
    }
    steps = atoi(argv[5]);
    h = atof(argv[6]);
    list = argv[7];
    for (item = strtok(list, ","); item && n_out < MAX_VALUES; item = strtok(NULL, ","))
        out_vrs[n_out++] = (vr_t)strtoul(item, NULL, 10);
    for (k = 8; k < argc && n_set < MAX_VALUES; k++) {
        char *eq = strchr(argv[k], '=');
        if (!eq || !strchr("riR", argv[k][0])) {
            fprintf(stderr, "harness: bad setting %s\n", argv[k]);
            return 2;
        }
        settings[n_set].kind = argv[k][0];
        settings[n_set].vr = (vr_t)strtoul(argv[k] + 1, NULL, 10);
        settings[n_set].value = atof(eq + 1);
        n_set++;
    }
    if (strcmp(argv[2], "fmi2") == 0)
        run_fmi2(argv[3], argv[4], steps, h, settings, n_set);
    else
        run_fmi3(argv[3], argv[4], steps, h, settings, n_set);
    return 0;
}
