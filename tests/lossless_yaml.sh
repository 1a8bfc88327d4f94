# lossless_yaml.sh - sourced by tests/cli/lib.sh and tests/bench.sh: the
# lossless pipeline (voxelize, DAG, SSVDAG, encodings) as YAML on stdout,
# the runner tests' and benchmarks' common case.
#   lossless_yaml NAME MESH LEVELS CHUNK_LEVEL RESOURCES
# RESOURCES is the flow mapping of `resources:`, e.g.
#   "{jobs: 2, threads: 1, mem_budget: 2GiB, job_mem_budget: 512M}".
lossless_yaml() {
	cat <<YAML
version: 1
name: $1
input:
  mesh: $2
levels: $3
chunk_level: $4
resources: $5
jobs:
  vox:    {stage: voxelize}
  dag:    {stage: svo-to-dag, needs: [vox]}
  ssvdag: {stage: symmetry-merge, needs: [dag]}
  enc:    {stage: encode, needs: [dag, ssvdag]}
YAML
}
