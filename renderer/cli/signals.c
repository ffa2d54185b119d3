/* signals.c: Ctrl-C and SIGTERM for the command line (docs/cli.md, "Signals"). Before there is
 * anything to write a signal ends the process at once; during a bake the first one is noted in
 * the cancel flag, which stops the tracing and the guide bake, and nothing is written; while
 * there is something to write, it is noted in the cancel flag, polled by the render and compare
 * loops, and what was done is written. */
#define _DEFAULT_SOURCE /* SA_RESTART */
#include "cli.h"

#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* The one piece of mutable global state: the number of the first SIGINT or SIGTERM received
 * (0: none yet). Set by on_signal_stop, polled between pixels through rd_render_opts.cancel. */
static volatile sig_atomic_t interrupted = 0;

/* Both signals get one treatment (docs/cli.md, "Signals"). While a handler runs, the other
 * signal is blocked (sa_mask), so a SIGINT and a SIGTERM arriving together count as a first and a
 * second signal, not as two firsts. */
static void handle_stop_signals(void (*fn)(int))
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = fn;
    sigemptyset(&sa.sa_mask);
    sigaddset(&sa.sa_mask, SIGINT);
    sigaddset(&sa.sa_mask, SIGTERM);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    /* A blocked mask is inherited through exec: unblock them, or they would never arrive. */
    sigset_t both;
    sigemptyset(&both);
    sigaddset(&both, SIGINT);
    sigaddset(&both, SIGTERM);
    sigprocmask(SIG_UNBLOCK, &both, NULL);
}

/* The first signal of a bake (cancel), a render's passes or the writing of any outputs (stop):
 * note it, then let the next one end the process at once (default action). Only
 * async-signal-safe calls here (sigaction, write, raise; POSIX.1-2008 2.4.3). Every output goes
 * through a temporary name and a rename, so being killed mid-write keeps the previous files. */
static void note_first_signal(int sig, const char *msg, size_t len)
{
    static const struct sigaction dfl = {.sa_handler = SIG_DFL};
    /* Two threads can take a SIGINT and a SIGTERM at the same moment, each running this
     * handler: only the one that turns `interrupted` from 0 to its signal (atomically; a
     * lock-free compare-and-swap is async-signal-safe) is the first. The other is a second
     * signal: with its default action back, re-raised, it ends the process when this returns. */
    if (!__sync_bool_compare_and_swap(&interrupted, 0, sig)) {
        sigaction(sig, &dfl, NULL);
        raise(sig);
        return;
    }
    sigaction(SIGINT, &dfl, NULL);
    sigaction(SIGTERM, &dfl, NULL);
    if (len > 0) {
        ssize_t r = write(STDERR_FILENO, msg, len);
        (void)r;
    }
}

static void on_signal_stop(int sig)
{
    static const char msg[] = "\nphotonmarch: stopping; writing what it has (a second Ctrl-C or SIGTERM ends at once)\n";
    note_first_signal(sig, msg, sizeof msg - 1);
}

/* During a bake: the same, silently; the command prints its one line when the bake has
 * stopped (cli_report_cancelled). */
static void on_signal_cancel(int sig) { note_first_signal(sig, "", 0); }

/* Before there is anything to write (loading the scene): end at once with the documented
 * status. */
static void on_signal_quit(int sig)
{
    static const char msg[] = "\nphotonmarch: interrupted before anything was rendered; nothing written\n";
    ssize_t r = write(STDERR_FILENO, msg, sizeof msg - 1);
    (void)r;
    _exit(128 + sig);
}

/* The exit status after signal `sig`: 128 + its number, the shell's convention (130 SIGINT,
 * 143 SIGTERM). */
int cli_exit_interrupted(int sig) { return 128 + sig; }

/* Install the handlers: cli.h. */
void cli_on_signal_quit(void) { handle_stop_signals(on_signal_quit); }
void cli_on_signal_stop(void) { handle_stop_signals(on_signal_stop); }
void cli_on_signal_cancel(void) { handle_stop_signals(on_signal_cancel); }

int cli_report_cancelled(const char *cmd, const char *what)
{
    fprintf(stderr, "photonmarch %s: interrupted %s; nothing written, the previous files are as they were\n", cmd, what);
    return cli_exit_interrupted(interrupted ? interrupted : SIGINT);
}

const volatile sig_atomic_t *cli_cancel_flag(void) { return &interrupted; }
int cli_interrupted(void) { return interrupted; }
