#!/usr/bin/env bash
# bench_cost_fit.sh: the tile selection's cost weights (renderer/integrators/select.c, the head),
# fitted again on this build (run by hand after a change to what a sample costs;
# docs/guided-marching.md "Where marching pays", docs/benchmarks.md).
#
# The selection counts a camera sample's cost as work, in units of one density lookup:
#     C = lookups + w_S shadow rays + w_M marcher PDF segments + w_F flight segments
#         + w_V guided vertices + w_0,
# so that the same seed gives the same choices on any machine. The weights come from a
# least-squares fit of time per camera sample on the calibration scenes, which are not in the
# benchmark's tables: each scene rendered by delta, guided and guided-unbiased with select off
# (every sample of the method), one thread, ROUNDS interleaved rounds, the median time. Each
# render gives one equation,
#     t / samples = a_L lookups + a_S shadow rays + a_M marcher segments + a_F flight segments
#                   + a_V guided vertices + a_0         (all per camera sample, a in us),
# fitted for relative error (each row divided by its t). The weights are the a over a_L.
# bench/cost_fit.py prints the fit, the weights, and each render's measured and modelled time.
#
# FIT=beams fits the weight of march.ls nee+beams' balls instead, the others held at
# select.c's: guided with nee+beams (one fixed photon map, select off) on the same scenes,
#     t / samples - (held terms) = a_H balls crossed    (per camera sample),
# the held terms in us by select.c's weights times the lookup's 0.164 us.
# FIT=gu fits guided-unbiased's two weights (flight segment, guided vertex) the same way, the
# lookup, shadow ray, equiangular set-up and camera sample held: guided-unbiased alone, select off,
#     t / samples - (held terms) = a_F flight segments + a_V guided vertices.
# FIT=eq fits the weight of a flight's equiangular set-up (the choice of lights of "auto",
# rd_track_counters.eq_flights): delta with settings.equiangular "auto" and "false" on the same
# scenes, paired (the scenes with no point or spot light set nothing up and drop out),
#     (t_auto - t_off) / samples - (held terms of the difference) = a_E set-ups.
#
# FIT=eqs fits the weight of an equiangular sample's own work (the light and distance it draws,
# the MIS weight's majorant walk: all but its one lookup, its transmittance's lookups and its
# shadow ray, which count as such): delta with settings.equiangular "true" and "false", paired,
#     (t_true - t_off) / samples - (held terms, the set-ups' included) = a_Z samples.
#
# FIT=ms fits the weight of a marched sample's own work (its inversion of the PDF, its source's
# set-up, the light's lit range, the continuation's set-up: all but its lookups, shadow rays and
# equiangular set-ups, which count as such; the difference's PDF segments are held too): guided
# with march.min_samples = march.max_samples 16 and 2 on the same scenes, select off, paired
# (the PDF's segments are the same in both; session 49),
#     (t_16 - t_2) / samples - (held terms of the difference) = a_P marched samples.
# Session 49: 0.085 lookups, not charged (docs/benchmarks.md "Session 49"). That fit holds the
# lookup at one time for every scene, and what a lookup costs differs between scenes.
#
# FIT=rel fits the marcher's two weights, a PDF segment w_M and a marched sample w_P, as the
# selection uses them: against delta's cost on the same scene. Each scene is rendered by delta,
# by guided and by guided with march.min_samples = march.max_samples = 16 (select off); delta's
# time a counted lookup on the scene, k = (t / samples) / C_delta, turns guided's time into
# lookups, and
#     (t / samples) / k = held counts (weights held at select.c's) + w_M segments + w_P samples
# is fitted for relative error over the scenes' guided rows. Session 49: w_M 0.66, w_P 1.63 (the
# model within 0.90-1.18 of the twelve rows, select.c's 0.82-1.38); tried in the selection and
# not kept: no gain at 10 s, losses on the dense block and sphere-in-fog (docs/benchmarks.md
# "Session 49").
# FIT=relp: the same renders as rel (into the same OUT; `python3 bench/cost_fit.py relp
# OUT/runs.txt` fits it on rel's runs without rendering again), the marched sample's weight
# alone fitted, the PDF segment held at select.c's 1.52. Session 51: 0.22 lookups.
# FIT=relcheck: the same renders, no fit: each scene's model over measured time with select.c's
# weights and with session 51's rel and relp fits, for scenes the fits did not see. Session 51,
# SCENES="homogeneous hard-narrow-spot beam": select.c's weights read guided with 16 samples on
# every ray at 0.73, 0.46 and 0.85 of its time (docs/benchmarks.md "Session 51").
#
#   bench/bench_cost_fit.sh [BIN]
#       environment: SCENES (the six below), SPP (16), RES ([160,120]), ROUNDS (3),
#                    FIT (all, beams, gu, eq, eqs, ms, rel, relp or relcheck), OUT (bench/results/cost_fit,
#                    cost_fit_beams, cost_fit_gu, cost_fit_eq, cost_fit_eqs, cost_fit_ms, cost_fit_rel)
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/machine.sh
bench_machine_note
BIN=${1:-build/photonmarch}
# glass-fog (session 21): its spot lights the fog by way of glass, so the marchers' march.ls
# defaults to nee+beams with progressive passes there (docs/scene-format.md) and `compare`
# renders a photon reference unless one is given; to measure nee+paths there as before, name
# it in the variant (march.ls=nee+paths) or leave glass-fog out of SCENES.
SCENES=${SCENES:-cloud smoke-vdb glass-fog sphere-in-fog hetero-forward noise-block}
SPP=${SPP:-16}
RES=${RES:-[160,120]}
ROUNDS=${ROUNDS:-3}
FIT=${FIT:-all}
case $FIT in
  beams) OUT=${OUT:-bench/results/cost_fit_beams} ;;
  gu) OUT=${OUT:-bench/results/cost_fit_gu} ;;
  eq) OUT=${OUT:-bench/results/cost_fit_eq} ;;
  eqs) OUT=${OUT:-bench/results/cost_fit_eqs} ;;
  ms) OUT=${OUT:-bench/results/cost_fit_ms} ;;
  rel|relp) OUT=${OUT:-bench/results/cost_fit_rel} ;;
  relcheck) OUT=${OUT:-bench/results/cost_fit_relcheck} ;;
  *) OUT=${OUT:-bench/results/cost_fit} ;;
esac
mkdir -p "$OUT"
log=$OUT/runs.txt
: > "$log"
if [ "$FIT" = beams ]; then
  methods=guided
  extra=(--set march.ls='"nee+beams"' --set photons.progressive=false)
elif [ "$FIT" = gu ]; then
  methods=guided-unbiased
  extra=(--set guide.distances=true) # the flight segments the fit weighs (off by default since session 46)
elif [ "$FIT" = eq ]; then
  methods="delta-auto delta-off"
  extra=()
elif [ "$FIT" = eqs ]; then
  methods="delta-true delta-off"
  extra=()
elif [ "$FIT" = ms ]; then
  methods="guided-n16 guided-n2"
  extra=()
elif [ "$FIT" = rel ] || [ "$FIT" = relp ] || [ "$FIT" = relcheck ]; then
  methods="delta guided guided-n16"
  extra=()
else
  methods="delta guided guided-unbiased"
  extra=()
fi
for r in $(seq "$ROUNDS"); do
  for name in $SCENES; do
    for m in $methods; do
      o=$OUT/$name-$m.exr
      # FIT=eq's two variants are delta with settings.equiangular auto and off
      meth=$m variant=()
      case $m in
        delta-auto) meth=delta variant=(--set settings.equiangular='"auto"') ;;
        delta-off) meth=delta variant=(--set settings.equiangular=false) ;;
        delta-true) meth=delta variant=(--set settings.equiangular=true) ;;
        guided-n*) meth=guided variant=(--set march.min_samples=${m#guided-n} --set march.max_samples=${m#guided-n}) ;;
      esac
      "$BIN" render "scenes/$name.json" --method "$meth" --spp "$SPP" --threads 1 \
        --set settings.select='"off"' --set camera.resolution="$RES" "${extra[@]}" "${variant[@]}" -o "$o" > /dev/null 2>&1
      jq -c --arg s "$name" --arg m "$m" '{scene: $s, method: $m, t: .render_seconds, n: .paths,
          L: .density_lookups, S: .shadow_rays, E: (.equiangular_flights // 0),
          Z: (.equiangular_samples // 0),
          M: ((.march.rays // 0) * (.march.pdf_segments_per_ray // 0)),
          P: ((.march.rays // 0) * (.march.samples_per_ray // 0)),
          F: ((.guided_paths.flight_segments_per_path // 0) * .paths),
          V: ((.guided_paths.guide_vertices_per_path // 0) * .paths),
          Q: (.march.beam_queries // 0),
          H: ((.march.beam_queries // 0) * (.march.balls_per_query // 0))}' "${o%.exr}.json" >> "$log"
    done
  done
done

# The fit itself (bench/cost_fit.py): the weights and each render's measured and modelled time.
python3 bench/cost_fit.py "$FIT" "$log"
