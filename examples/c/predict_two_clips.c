/* Load an egopd model once, predict two clips on it and print the total force per frame.
 *
 *   predict_two_clips [--model DIR] [--frames N] [--size S] [--steps N] [--seed S] [--out DIR] [--csv PREFIX]
 *                     [CLIP1 [CLIP2]]
 *
 * CLIP: a video file or frame folder; "-" or missing: the built-in sample clip. Without --model: the built-in tiny
 * synthetic model. --out DIR writes each clip's usual output folder (DIR/clip1, DIR/clip2); --csv PREFIX writes
 * each clip's taxels [F, 162] in newtons to PREFIX1.csv, PREFIX2.csv (the layout of taxels.csv, 17 digits).
 * Build: cc predict_two_clips.c $(pkg-config --cflags --libs egopd), or CMake find_package(egopd) (CMakeLists.txt).
 */
#include <egopd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void log_line(void* user, const char* line) {
  (void)user;
  fprintf(stderr, "  %s\n", line);
}

static int show_step(void* user, const egopd_progress* p) {
  (void)user;
  if (strcmp(p->stage, "denoise") == 0) fprintf(stderr, "  step %d/%d (%.2f s)\n", p->step, p->steps, p->step_seconds);
  return 0; /* non-zero would cancel the prediction */
}

static int write_csv(const char* path, const egopd_result* r) {
  const int64_t frames = egopd_result_frames(r), taxels = egopd_result_num_taxels(r);
  const double* v = egopd_result_taxels(r);
  FILE* f = fopen(path, "w");
  if (!f) return -1;
  fprintf(f, "frame");
  for (int64_t m = 0; m < taxels; ++m) fprintf(f, ",p%lld", (long long)m);
  fprintf(f, "\n");
  for (int64_t t = 0; t < frames; ++t) {
    fprintf(f, "%lld", (long long)t);
    for (int64_t m = 0; m < taxels; ++m) fprintf(f, ",%.17g", v[t * taxels + m]);
    fprintf(f, "\n");
  }
  return fclose(f);
}

int main(int argc, char** argv) {
  const char* model_dir = NULL;
  const char* out = NULL;
  const char* csv = NULL;
  const char* clips[2] = {NULL, NULL};
  int nclips = 0;
  egopd_load_options lo;
  egopd_predict_options po;
  egopd_load_options_init(&lo);
  egopd_predict_options_init(&po);
  lo.log = log_line;
  for (int i = 1; i < argc; ++i) {
    const char* a = argv[i];
    const char* v = i + 1 < argc ? argv[i + 1] : NULL;
    if (a[0] == '-' && a[1] == '-' && !v) {
      fprintf(stderr, "predict_two_clips: %s needs a value\n", a);
      return 2;
    }
    if (strcmp(a, "--model") == 0) model_dir = v, ++i;
    else if (strcmp(a, "--frames") == 0) po.num_frames = atoll(v), ++i;
    else if (strcmp(a, "--size") == 0) lo.size = atoll(v), ++i;
    else if (strcmp(a, "--steps") == 0) po.steps = atoi(v), ++i;
    else if (strcmp(a, "--seed") == 0) po.seed = strtoull(v, NULL, 10), ++i;
    else if (strcmp(a, "--out") == 0) out = v, ++i;
    else if (strcmp(a, "--csv") == 0) csv = v, ++i;
    else if (nclips < 2) clips[nclips++] = strcmp(a, "-") == 0 ? NULL : a;
    else {
      fprintf(stderr, "predict_two_clips: unexpected argument '%s'\n", a);
      return 2;
    }
  }

  egopd_model* model = NULL;
  printf("egopd %s\n", egopd_version());
  if (egopd_model_load(model_dir, &lo, &model) != EGOPD_OK) {
    fprintf(stderr, "predict_two_clips: %s\n", egopd_last_error());
    return 1;
  }
  printf("model: %s\n", egopd_model_dir(model));
  po.progress = show_step;
  int status = 0;
  for (int k = 0; k < 2 && status == 0; ++k) {
    char dir[4096], path[4096];
    po.video = clips[k];
    po.out_dir = NULL;
    if (out) {
      snprintf(dir, sizeof dir, "%s/clip%d", out, k + 1);
      po.out_dir = dir;
    }
    egopd_result* r = NULL;
    if (egopd_predict(model, &po, &r) != EGOPD_OK) {
      fprintf(stderr, "predict_two_clips: clip %d: %s\n", k + 1, egopd_last_error());
      status = 1;
      break;
    }
    printf("clip %d (%s): %lld frames, mean %.2f N, peak %.2f N\n", k + 1, clips[k] ? clips[k] : "built-in sample",
           (long long)egopd_result_frames(r), egopd_result_mean_force(r), egopd_result_peak_force(r));
    for (int64_t f = 0; f < egopd_result_frames(r); ++f)
      printf("  frame %2lld: %10.3f N%s\n", (long long)f, egopd_result_total_force(r)[f],
             egopd_result_contact(r)[f] ? "  contact" : "");
    if (csv) {
      snprintf(path, sizeof path, "%s%d.csv", csv, k + 1);
      if (write_csv(path, r) != 0) {
        fprintf(stderr, "predict_two_clips: %s: cannot write\n", path);
        status = 1;
      }
    }
    egopd_result_free(r);
  }
  egopd_model_free(model);
  return status;
}
