#!/usr/bin/env bash
# Regenerate the shipped models (onnx/models/<task>/) from nothing, on this machine:
#   1. dips datagen   CSVTO demos in the world (both cores per task)
#   2. dips train     prior.json, denoiser.onnx, discriminator.onnx (one core per task; the
#                     two tasks train side by side)
#   3. dips train --policy   the Diffusion Policy baseline, policy/denoiser.onnx (~18 min
#                     per task, side by side)
#   4. dips model quality / card   figures on the held-out demos, MODEL_CARD.md
# Every step resumes after a kill: rerun the script. About 2 h on 2 cores
# (docs/training.md, "Shipped models"). Settings: onnx/models/<task>/settings.json.
#
# Environment: DEMOS_SCREWDRIVER (default 40), MARKOV_SCREWDRIVER (default 40: screwdriver
# demos whose sequences are drawn from the paper's Markov prior, seeds 100 on; docs/datagen.md),
# DEMOS_CARD (default 128), WORK (default target/models-work: datasets, checkpoints and logs;
# not committed), TASKS (default "screwdriver card"), SEED (default 0: the training seed; the
# data do not depend on it). SEED=0 writes the shipped models, onnx/models/<task>/; any other
# seed writes onnx/models/<task>-seed<SEED>/ from the same data and settings, to measure how
# much a result depends on the training run (docs/training.md, "Training seeds").
# CARD_GOALS (default capped, ours): `paper` makes the card's demos with the paper's goals
# (`dips datagen --card-goals paper`: every push aims 2 cm on) into WORK/data/card-paper and
# writes onnx/models/card-paper[-seed<SEED>]/ (docs/training.md, "The paper's card").
# OBJECT_FRAME (default world): `segment-start` trains denoisers that measure the object from
# each segment's start (`dips train --object-frame`, docs/training.md, "The card's short
# pushes") from the same data, into onnx/models/<name>-start[-seed<SEED>]/.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${WORK:-target/models-work}
SEED=${SEED:-0}
read -r -a TASK_LIST <<<"${TASKS:-screwdriver card}"
declare -A DEMOS=([screwdriver]=${DEMOS_SCREWDRIVER:-40} [card]=${DEMOS_CARD:-128})
mkdir -p "$WORK/logs"
CARD_GOALS=${CARD_GOALS:-capped}
case "$CARD_GOALS" in paper | capped) ;; *)
  echo "CARD_GOALS=$CARD_GOALS: expected paper or capped" >&2
  exit 2
  ;;
esac
OBJECT_FRAME=${OBJECT_FRAME:-world}
case "$OBJECT_FRAME" in world | segment-start) ;; *)
  echo "OBJECT_FRAME=$OBJECT_FRAME: expected world or segment-start" >&2
  exit 2
  ;;
esac
# A task's data name: the card with the paper's goals is card-paper.
data_name() { [[ $1 == card && $CARD_GOALS == paper ]] && echo "card-paper" || echo "$1"; }
# A task's model name: the data's, with -start for models in the segment-start frame.
name() { [[ $OBJECT_FRAME == segment-start ]] && echo "$(data_name "$1")-start" || data_name "$1"; }
# Where a task's models of this seed are trained and where they are shipped.
suffix() { [[ $SEED == 0 ]] && echo "" || echo "-seed$SEED"; }
work_models() { echo "$WORK/models/$(name "$1")$(suffix)"; }
shipped() { echo "onnx/models/$(name "$1")$(suffix)"; }
data() { echo "$WORK/data/$(data_name "$1")"; }
# The shipped default models' folder holds their settings; every other folder gets a copy.
own_settings() { [[ $(shipped "$1") == "onnx/models/$1" ]]; }

# DIPS: a dips binary to use (default: build target/release/dips), e.g. a copy that a later
# build cannot replace while a long run goes on.
if [[ -z ${DIPS:-} ]]; then
  cargo build --release -p dips-cli
  DIPS=target/release/dips
fi

for task in "${TASK_LIST[@]}"; do
  echo "== datagen $task (${DEMOS[$task]} demos)"
  goals=()
  [[ $task == card ]] && goals=(--card-goals "$CARD_GOALS")
  "$DIPS" datagen --task "$task" "${goals[@]}" --demos "${DEMOS[$task]}" --out "$(data "$task")"
done
MARKOV=${MARKOV_SCREWDRIVER:-40}
if [ "$MARKOV" -gt 0 ] && [[ " ${TASK_LIST[*]} " == *" screwdriver "* ]]; then
  echo "== datagen screwdriver ($MARKOV demos from the Markov prior)"
  "$DIPS" datagen --task screwdriver --demos "$MARKOV" --first-seed 100 --sequences markov \
    --out "$WORK/data/screwdriver"
fi

pids=()
for task in "${TASK_LIST[@]}"; do
  log="$WORK/logs/train-$(name "$task")$(suffix).log"
  echo "== train $(name "$task"), seed $SEED (log: $log)"
  "$DIPS" train --task "$task" --data "$(data "$task")" --out "$(work_models "$task")" \
    --settings "onnx/models/$task/settings.json" --seed "$SEED" --object-frame "$OBJECT_FRAME" \
    --quiet > "$log" 2>&1 &
  pids+=($!)
done
for p in "${pids[@]}"; do wait "$p"; done

# The Diffusion Policy baseline has no start frame: models in the segment-start frame train
# none and get a copy of the world-frame folder's (onnx/models/<data name>[-seed<SEED>]/policy/,
# the same files), so that every method runs from their folder.
if [[ $OBJECT_FRAME == world ]]; then
  pids=()
  for task in "${TASK_LIST[@]}"; do
    log="$WORK/logs/policy-$(name "$task")$(suffix).log"
    echo "== train the diffusion-policy baseline for $(name "$task"), seed $SEED (log: $log)"
    "$DIPS" train --policy --task "$task" --data "$(data "$task")" \
      --out "$WORK/models/$(name "$task")-policy$(suffix)" --settings "onnx/models/$task/policy/settings.json" \
      --seed "$SEED" --quiet > "$log" 2>&1 &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p"; done
  for task in "${TASK_LIST[@]}"; do
    mkdir -p "$(shipped "$task")/policy"
    own_settings "$task" || cp "onnx/models/$task/policy/settings.json" "$(shipped "$task")/policy/"
    for f in denoiser.onnx train_report.json; do
      cp "$WORK/models/$(name "$task")-policy$(suffix)/$f" "$(shipped "$task")/policy/$f"
    done
  done
fi

for task in "${TASK_LIST[@]}"; do
  out="$(shipped "$task")"
  mkdir -p "$out"
  if [[ $OBJECT_FRAME == segment-start ]]; then
    policy="onnx/models/$(data_name "$task")$(suffix)/policy"
    if [[ -d $policy ]]; then
      rm -rf "$out/policy"
      cp -r "$policy" "$out/policy"
    fi
    # The settings as trained, frame included (the task's file does not name it).
    python3 -c 'import json, sys; print(json.dumps(json.load(open(sys.argv[1]))["settings"], indent=2))' \
      "$(work_models "$task")/train_report.json" > "$out/settings.json"
  else
    own_settings "$task" || cp "onnx/models/$task/settings.json" "$out/settings.json"
  fi
  for f in denoiser.onnx discriminator.onnx prior.json train_report.json; do
    cp "$(work_models "$task")/$f" "$out/$f"
  done
  echo "== quality $task"
  "$DIPS" model quality --task "$task" --models "$out" --data "$(data "$task")"
  "$DIPS" model card --task "$task" --models "$out" \
    --command "SEED=$SEED TASKS=$task CARD_GOALS=$CARD_GOALS OBJECT_FRAME=$OBJECT_FRAME scripts/make-models.sh"
done
