#!/usr/bin/env bash
# Sampler workers for a holodeck server, as a Slurm job array.
#
# Workers are stateless: tasks may start late, be preempted or end early; the
# server gives their unfinished packets back to its schedule.
#
#   holodeck serve room.hdk --listen 0.0.0.0:7777      # on a host the nodes can reach (TLS: the
#                                                      # token file pins its certificate)
#   sbatch --export=ALL,HOLODECK_SERVER=login1:7777 slurm-array.sh
#
#SBATCH --job-name=holodeck-samplers
#SBATCH --array=0-31
#SBATCH --cpus-per-task=8
#SBATCH --mem=8G
#SBATCH --time=04:00:00
#SBATCH --requeue
set -euo pipefail

: "${HOLODECK_SERVER:?set HOLODECK_SERVER to host:port of holodeck serve}"
SCENE=${HOLODECK_SCENE:-scenes/room.toml}
# Samplers need writer access only: the writer token, never the admin one.
TOKEN_FILE=${HOLODECK_TOKEN_FILE:-room.hdk.writer.token}

# One worker connection per CPU; each array task traces its own random sequence.
exec holodeck sample "$SCENE" \
  --connect "$HOLODECK_SERVER" \
  --token-file "$TOKEN_FILE" \
  -j "${SLURM_CPUS_PER_TASK:-1}" \
  --seed "$(( ${SLURM_ARRAY_JOB_ID:-0} * 1000 + ${SLURM_ARRAY_TASK_ID:-0} ))"
