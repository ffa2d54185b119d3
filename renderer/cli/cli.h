/* cli.h: the inside of the photonmarch command line (renderer/cli/), not part of the library.
 * main.c dispatches to one cmd_<name>.c per subcommand; they share common.c (options, exit
 * codes, output checks, default names, the cached bake) and signals.c (Ctrl-C and SIGTERM).
 * Everything here reaches the renderer only through renderer.h. Dependencies point one way:
 * main.c -> cmd_*.c -> common.c, signals.c, ranks.c. Under an MPI launcher main.c starts
 * dist/ (rd_dist.h) and hands it to the commands that run on several ranks (docs/cluster.md). */
#ifndef CLI_H
#define CLI_H

#include "dist/rd_dist.h"
#include "renderer.h"

#include <signal.h>
#include <stddef.h>

/* Exit codes: 0 success; 1 usage error (unknown command or option, bad option value);
 * 2 invalid input (scene, volume or other input file); 3 output could not be written;
 * 4 internal error; 128 + N after signal N: 130 for SIGINT (Ctrl-C), 143 for SIGTERM (what was
 * rendered so far was written). */
enum { CLI_EXIT_USAGE = 1, CLI_EXIT_INPUT = 2, CLI_EXIT_OUTPUT = 3, CLI_EXIT_INTERNAL = 4 };

/* ---- the subcommands: argv holds the arguments after the command's name; returns the exit
 * code. ---------------------------------------------------------------------------------- */

int cli_cmd_render(int argc, char **argv);
/* render on the ranks of d (NULL: alone, as cli_cmd_render): every rank calls it. */
int cli_cmd_render_on(int argc, char **argv, rd_dist *d);
int cli_cmd_info(int argc, char **argv);
int cli_cmd_voxelize(int argc, char **argv);
int cli_cmd_bake(int argc, char **argv);
/* bake on the ranks of d (NULL: alone, as cli_cmd_bake): every rank calls it. */
int cli_cmd_bake_on(int argc, char **argv, rd_dist *d);
int cli_cmd_explain(int argc, char **argv);
int cli_cmd_compare(int argc, char **argv);
/* compare on the ranks of d (NULL: alone, as cli_cmd_compare): every rank calls it. */
int cli_cmd_compare_on(int argc, char **argv, rd_dist *d);

/* ---- options (common.c) ------------------------------------------------------------------ */

/* Options shared by the commands that load a scene. */
typedef struct {
    const char *scene;
    rd_override ov[64];
    int nov;
    char ovbuf[64][512];
} cli_scene_args;

/* Consume --set at argv[*i]; returns 1 if handled, 0 if not --set, -1 on error (after a
 * message). */
int cli_take_set(cli_scene_args *a, int argc, char **argv, int *i);
/* The positional SCENE, or an unknown option: returns 0 when taken, CLI_EXIT_USAGE after a
 * message. */
int cli_take_positional(cli_scene_args *a, const char *cmd, const char *o);
/* 0 when a SCENE was given, else CLI_EXIT_USAGE after a message. */
int cli_need_scene(const cli_scene_args *a, const char *cmd);
/* The value `s` of option `opt` as a number in [lo, hi]: 1 and *out set, or 0 after a message. */
int cli_parse_int(const char *opt, const char *s, long lo, long hi, long *out);
int cli_parse_double(const char *opt, const char *s, double lo, double hi, double *out);

/* ---- errors and outputs (common.c) ------------------------------------------------------- */

/* The exit code of a renderer status. */
int cli_exit_for(rd_status st);
/* Print the renderer's one-line message `err` on stderr; returns cli_exit_for(st). */
int cli_report_error(rd_status st, const char *err);
/* 0 unless `out` is the input `scene` (the same file): then CLI_EXIT_USAGE after a message
 * naming `cmd`. */
int cli_refuse_input_as_output(const char *cmd, const char *out, const char *scene);
/* 1 when both paths exist and are one file (the same device and inode). */
int cli_same_file(const char *out, const char *in);
/* out/<scene file name without extension><suffix> into out[n]. */
void cli_default_output(const char *scene, const char *suffix, char *out, size_t n);
/* Bake what `bo` asks for through the cache folder beside `out` (OUT's folder, then
 * .photonmarch-cache), or afresh with `fresh`; a cache that cannot be saved is a warning.
 * *baked is the caller's (rd_baked_free). */
rd_status cli_bake_beside(const rd_scene *scene, const rd_bake_opts *bo, const char *out, int fresh,
                          int quiet, rd_baked **baked, char *err, size_t errlen);

/* ---- progress (common.c) ----------------------------------------------------------------- */

/* What a progress printer keeps between calls: the time limit (0: none), whether stderr is a
 * terminal, and when it last printed (cli_wall_seconds; 0: never). */
typedef struct {
    double time_limit;
    int tty;
    double last_print;
} cli_progress_state;

/* Seconds on a monotonic clock. */
double cli_wall_seconds(void);

/* ---- signals (signals.c) ----------------------------------------------------------------- */

/* Before there is anything to write: a SIGINT or SIGTERM ends the process at once with
 * 128 + N after a message. */
void cli_on_signal_quit(void);
/* While there is something to write: the first SIGINT or SIGTERM is noted (the cancel flag)
 * so the work stops and writes what it has; a second one ends the process at once. */
void cli_on_signal_stop(void);
/* During a bake (rd_bake_opts.cancel = cli_cancel_flag()): the first signal is noted silently,
 * so the bake stops and removes its temporaries; a second one ends the process at once. */
void cli_on_signal_cancel(void);
/* The one line after a bake stopped by a signal, "photonmarch CMD: interrupted WHAT; nothing
 * written, ...", on stderr; returns the exit status (130 / 143). */
int cli_report_cancelled(const char *cmd, const char *what);
/* The flag for rd_render_opts.cancel and rd_cmp_opts.cancel: the first signal's number. */
const volatile sig_atomic_t *cli_cancel_flag(void);
/* The number of the first SIGINT or SIGTERM received (0: none yet). */
int cli_interrupted(void);
/* The exit status after signal `sig`: 128 + its number (130 SIGINT, 143 SIGTERM). */
int cli_exit_interrupted(int sig);

/* ---- several ranks (ranks.c; docs/cluster.md) --------------------------------------------
 * Every function here is collective when d has several ranks (every rank calls it, in the same
 * order), and does the one-process thing when d is NULL. */

/* Agree on a step's outcome: code is this rank's exit code for the step (0: it went well), msg
 * its one-line message when it failed (NULL: nothing to print). Alone: prints msg, returns code.
 * Several ranks: when every rank failed, rank 0 prints its message (the same input fails the
 * same way everywhere); when only some did, each of them prints "photonmarch: rank K of N: msg"
 * and the others nothing. Returns 0 when every rank went well, else this rank's code or, on a
 * rank that did not fail, the largest code of those that did. */
int cli_ranks_agree(rd_dist *d, int code, const char *msg);
/* The same after a library step that agrees itself (rd_bake with comm: every rank returns the
 * failure): a rank whose msg ends in RD_ON_ANOTHER_RANK did not fail itself and stays silent,
 * the ranks that did fail speak as in cli_ranks_agree. Returns code (the same on every rank
 * after such a step). */
int cli_ranks_agree_shared(rd_dist *d, int code, const char *msg);
/* Around the options' parsing: on the ranks other than 0, stdout and stderr go to /dev/null
 * (rank 0 says what every rank would say); cli_ranks_unmute restores them and returns rank 0's
 * `code` (a rank whose code differs, its options not rank 0's, says so in one line). */
int cli_ranks_mute(rd_dist *d);
int cli_ranks_unmute(rd_dist *d, int saved, int code);
/* 0 when every rank read the same bytes at `path` (every rank loads its own copy of the scene),
 * else CLI_EXIT_INPUT after one line from rank 0. */
int cli_ranks_same_file(rd_dist *d, const char *path);
/* 0 when every rank passed the same `text` (its options that decide the outcome, as text) and
 * the same --set overrides in `a` (NULL: none), else CLI_EXIT_USAGE after one line from rank 0. */
int cli_ranks_same_options(rd_dist *d, const char *text, const cli_scene_args *a);
/* Load a's scene on every rank (*scene; the caller frees it, also after a failure) and agree:
 * 0 when every rank loaded it and read the same file, else the exit code after one line
 * (cli_ranks_agree, cli_ranks_same_file). */
int cli_ranks_load_scene(rd_dist *d, const cli_scene_args *a, rd_scene **scene);

#endif
