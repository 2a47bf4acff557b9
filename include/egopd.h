/* egopd: grasp pressure (162 glove taxels in newtons, and heatmaps) from an RGB clip, hint masks and a prompt,
 * with an EgoPressureDiff model on the CPU. C99; usable from C and C++. Link with -legopd (pkg-config egopd, or
 * CMake find_package(egopd) and the target egopd::egopd).
 *
 * Use: egopd_model_load() once, then egopd_predict() / egopd_counterfactual() any number of times, then
 * egopd_model_free(). Results are arrays owned by an egopd_result (egopd_result_free()).
 *
 * Errors: every function that can fail returns an egopd_status; EGOPD_OK is 0. The one-line message of the last
 * failure on the calling thread is egopd_last_error() (the same line the egopd command prints after "egopd: ").
 * No C++ exception ever leaves this API; a null or mis-sized argument is an error, never a crash.
 *
 * Thread safety:
 *  - Any function may be called from any thread. egopd_last_error() is per thread.
 *  - Computing calls (egopd_model_load, egopd_predict, egopd_counterfactual) run one at a time in a process: a call
 *    made while another is running waits for it. Each call uses the model's worker threads (all cores by default),
 *    so running two at once would not be faster. One model may therefore be used from several threads.
 *  - egopd_model_free() must not be called while a call on that model is running.
 *  - A result does not depend on its model (it may outlive it) and is never modified: it may be read from any thread.
 *  - The progress callback runs on the calling thread, inside the call; it must not call egopd_predict or
 *    egopd_counterfactual (that is an error: EGOPD_ERROR_ARGUMENT).
 *  - egopd never installs signal handlers. egopd_install_signal_handlers() (what the egopd command does) makes
 *    SIGINT/SIGTERM stop a running call at its next safe point with EGOPD_INTERRUPTED.
 */
#ifndef EGOPD_H
#define EGOPD_H

#include <stddef.h>
#include <stdint.h>

#if defined(__GNUC__)
#define EGOPD_API __attribute__((visibility("default")))
#else
#define EGOPD_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef enum egopd_status {
  EGOPD_OK = 0,
  EGOPD_ERROR = 1,          /* a file, model, clip or numeric failure (the message names it) */
  EGOPD_ERROR_ARGUMENT = 2, /* a null pointer, a mis-sized buffer or an option out of range */
  EGOPD_CANCELLED = 3,      /* the progress callback returned non-zero; nothing half-written was left */
  EGOPD_INTERRUPTED = 4,    /* SIGINT/SIGTERM, after egopd_install_signal_handlers() */
  EGOPD_ERROR_MEMORY = 5    /* out of memory */
} egopd_status;

/* The library's version ("0.1.0"). */
EGOPD_API const char* egopd_version(void);
/* The message of the last failed call on this thread ("" when none). Valid until the next call on this thread. */
EGOPD_API const char* egopd_last_error(void);
/* SIGINT/SIGTERM stop a running call at its next safe point (EGOPD_INTERRUPTED); a second signal exits at once. */
EGOPD_API void egopd_install_signal_handlers(void);
/* The signal recorded by those handlers (0: none), so a program can exit 128 + signal like the egopd command. */
EGOPD_API int egopd_pending_signal(void);

/* ---- loading a model ---- */

/* One line of the run's log (what the egopd command prints on stderr), without a newline. */
typedef void (*egopd_log_fn)(void* user, const char* line);

typedef struct egopd_load_options {
  size_t struct_size;        /* sizeof(egopd_load_options); set by egopd_load_options_init */
  int threads;               /* worker threads; 0: EGOPD_THREADS, else the physical cores. Process-wide (OpenMP) */
  int low_mem;               /* 1: load one component at a time and release it after use (same results) */
  const char* precision;     /* arithmetic of the model's calls: NULL or "fp32", "bf16" or "int8" (egopd --help) */
  int64_t size;              /* frame size S the model is prepared for (a multiple of 64); default 256 */
  const char* template_path; /* hand template JSON; NULL: the shipped (synthetic) template */
  egopd_log_fn log;          /* NULL: quiet */
  void* log_user;
  const char* conv;          /* 3x3 and temporal convolution algorithm: NULL (EGOPD_CONV, else "auto"),
                                "direct", "winograd" or "auto" (egopd --help, --conv) */
  int64_t block_cache_mb;    /* MiB of freed activation blocks kept for reuse while this model computes (set for
                                each of its calls; the blocks stay cached between calls, and are given back
                                when the last model is freed): -1 (the default):
                                EGOPD_BLOCK_CACHE_MB, else 1024; 0: none (low_mem models keep none);
                                at most 1048576 (egopd --help, --block-cache-mb) */
} egopd_load_options;

EGOPD_API void egopd_load_options_init(egopd_load_options* options);

typedef struct egopd_model egopd_model;

/* Loads a model directory (NULL or "": the built-in tiny synthetic model, created once in $XDG_CACHE_HOME/egopd or
 * ~/.cache/egopd, else in .egopd-default-model in the current folder; random weights, the pressures are not
 * meaningful). options may be NULL (defaults). */
EGOPD_API egopd_status egopd_model_load(const char* model_dir, const egopd_load_options* options,
                                        egopd_model** model);
/* Frees a model (NULL: nothing). Freeing the last model also gives back the activation blocks cached between calls
 * (block_cache_mb). */
EGOPD_API void egopd_model_free(egopd_model* model);
/* The folder the model was loaded from (the built-in model's cache folder for NULL). */
EGOPD_API const char* egopd_model_dir(const egopd_model* model);

/* ---- predicting ---- */

typedef struct egopd_progress {
  size_t struct_size;
  const char* stage;      /* "encode", "denoise" (after each sampler step), "decode", "write" */
  int step, steps;        /* denoise: sampler step (1-based) of steps; other stages 0, 0 */
  double step_seconds;    /* denoise: seconds of this step */
  double elapsed_seconds; /* since the call started */
  int variant, variants;  /* egopd_counterfactual: prompt variant (1-based) of variants; else 0, 0 */
} egopd_progress;
/* Return 0 to go on, non-zero to cancel the call (it returns EGOPD_CANCELLED; the model stays usable). */
typedef int (*egopd_progress_fn)(void* user, const egopd_progress* progress);

typedef struct egopd_predict_options {
  size_t struct_size; /* sizeof(egopd_predict_options); set by egopd_predict_options_init */
  /* The clip: a video file or frame folder, or RGB frames in memory, or neither (the built-in sample clip). */
  const char* video;
  const uint8_t* frames;    /* [frames_count, frames_height, frames_width, 3] RGB, row-major, caller-owned */
  size_t frames_bytes;      /* size of the frames buffer: count * height * width * 3 */
  int64_t frames_count, frames_height, frames_width;
  /* Hint masks (optional): a folder, or grey masks in memory (> 127 = hand), one per sampled frame or one per
   * source frame. */
  const char* masks_dir;
  const uint8_t* masks;     /* [masks_count, masks_height, masks_width] */
  size_t masks_bytes;       /* count * height * width */
  int64_t masks_count, masks_height, masks_width;
  /* The prompt: verbatim, or built from metadata fields (a META.json file or a JSON object text such as
   * {"obj_name": "a CocaCola", "weight": 355}), or none (no-text mode). At most one of the three. */
  const char* prompt;
  const char* meta_path;
  const char* meta_json;
  /* Sampling (the egopd predict options of the same names and defaults). */
  const char* sampler;      /* NULL/"": the model's scheduler; "euler" or "lcm" */
  int steps;                /* 0: the model's default (--sampler lcm on an Euler model: 4) */
  uint64_t seed;            /* 0 */
  int64_t num_frames;       /* frames sampled from the clip; 0: the model's default (16) */
  int64_t size;             /* 0: the size the model was loaded for; another size reloads the model for it */
  int has_guidance;         /* 0: the model's guidance; 1: guidance_min, guidance_max */
  float guidance_min, guidance_max;
  int64_t decode_chunk;     /* frames per VAE decode call; 0: all */
  /* Outputs: NULL: arrays only; a folder: also heatmap PNGs, side_by_side.mp4, taxels.csv, summary.json (for a
   * counterfactual: one folder per variant, comparison.png, forces.csv), written as a whole. */
  const char* out_dir;
  egopd_progress_fn progress; /* NULL: none */
  void* progress_user;
} egopd_predict_options;

EGOPD_API void egopd_predict_options_init(egopd_predict_options* options);

typedef struct egopd_result egopd_result;

/* One prediction. *result must be freed with egopd_result_free. */
EGOPD_API egopd_status egopd_predict(egopd_model* model, const egopd_predict_options* options,
                                     egopd_result** result);

/* The same clip and seed under every value of one prompt field (obj_name, weight, material, gender, age,
 * subj_weight, bodyfat; a bare number gets the field's unit, "omit" drops the field; the other fields come from
 * meta_path / meta_json). The clip is encoded once. results: an array of num_values pointers, filled in order. */
EGOPD_API egopd_status egopd_counterfactual(egopd_model* model, const egopd_predict_options* options,
                                            const char* field, const char* const* values, size_t num_values,
                                            egopd_result** results);

/* ---- results ---- */

EGOPD_API int64_t egopd_result_frames(const egopd_result* r);     /* F */
EGOPD_API int64_t egopd_result_size(const egopd_result* r);       /* S */
EGOPD_API int64_t egopd_result_num_taxels(const egopd_result* r); /* 162 */
/* [F, num_taxels] in newtons, row-major: the values of taxels.csv. */
EGOPD_API const double* egopd_result_taxels(const egopd_result* r);
/* [F, S, S] the drawn heatmaps (heatmap_NNN.png) in [0, 1]. */
EGOPD_API const float* egopd_result_heatmaps(const egopd_result* r);
/* [F] total force per frame (sum of the taxels) in newtons; [F] 1 where some taxel is in contact. */
EGOPD_API const double* egopd_result_total_force(const egopd_result* r);
EGOPD_API const uint8_t* egopd_result_contact(const egopd_result* r);
EGOPD_API double egopd_result_mean_force(const egopd_result* r);
EGOPD_API double egopd_result_peak_force(const egopd_result* r);
EGOPD_API double egopd_result_seconds(const egopd_result* r);
/* summary.json of the prediction (prompt, sampler, steps, per-frame forces, timings), also without out_dir. */
EGOPD_API const char* egopd_result_summary_json(const egopd_result* r);
/* Counterfactual results: the formatted value ("355g", "omit") and its folder name ("weight_355g"); else "". */
EGOPD_API const char* egopd_result_variant_value(const egopd_result* r);
EGOPD_API const char* egopd_result_variant_folder(const egopd_result* r);
EGOPD_API void egopd_result_free(egopd_result* r);

#ifdef __cplusplus
}
#endif

#endif /* EGOPD_H */
