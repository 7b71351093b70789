#!/usr/bin/env bash
# The paper's parameter studies on the free-fall benchmark (Sec. 5, Figs. 7-10), each with
# the adaptive steps that resolve the impacts and, for Figs. 8 and 9, also at the paper's
# fixed step (error and energy control off), and the round-off spread that Fig. 10's
# differences are measured against. Then the tables of examples/studies/README.md.
# Usage: bash examples/studies/run_all.sh [OUT_DIR] [extra sweep options, e.g. --workers 4]
# Each sweep resumes (and a finished single run is kept): run the script again to redo only
# missing or failed runs.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cases="$here/../free_fall"
out="${1:-studies}"
shift || true
fixed=(--set solver.error_tol=0 --set solver.energy_tol=0)
# Fig. 7: the two models, each from its own case file (IPIP with the paper's "zones" rule,
# which case_ipip.toml sets and a coarse-grained case cannot carry)
[ -f "$out/models/cg/summary.json" ]   || beamcontact run "$cases/case_cg_paper.toml" --out "$out/models/cg" --quiet
[ -f "$out/models/ipip/summary.json" ] || beamcontact run "$cases/case_ipip.toml"     --out "$out/models/ipip" --quiet
beamcontact compare "$out/models/cg" "$out/models/ipip" --point A --label CG --label IPIP --out "$out/models/models.png"
# Fig. 8: the IPIP penalty; Fig. 9: HHT's alpha; both resolved and at the fixed step
beamcontact sweep "$cases/case_ipip.toml" --set contact.penalty=1e5,1e6,1e7 --out "$out/penalty" "$@"
beamcontact sweep "$cases/case_ipip.toml" --set contact.penalty=1e5,1e6,1e7 "${fixed[@]}" --out "$out/penalty_fixed" "$@"
beamcontact sweep "$cases/case_ipip.toml" --set analysis.alpha=0,-0.1,-0.2,-0.33 --out "$out/alpha" "$@"
beamcontact sweep "$cases/case_ipip.toml" --set analysis.alpha=0,-0.1,-0.2,-0.33 "${fixed[@]}" --out "$out/alpha_fixed" "$@"
# Fig. 9 once more with IPIP "points" (a contact energy without jumps), so that HHT's own
# damping is not hidden by the energy that the "zones" set changes add
beamcontact sweep "$cases/case_ipip.toml" --set contact.pairing=points --set analysis.alpha=0,-0.1,-0.2,-0.33 --out "$out/alpha_points" "$@"
beamcontact sweep "$cases/case_ipip.toml" --set contact.pairing=points --set analysis.alpha=0,-0.1,-0.2,-0.33 "${fixed[@]}" --out "$out/alpha_points_fixed" "$@"
# Fig. 10: the coarse-grained cutoff, and the same case with the upper beam's density
# moved by -1 to +3 units in the last place (1.1e-16 of it each): the spread that round-off
# alone makes
beamcontact sweep "$cases/case_cg_paper.toml" --set contact.cutoff=0.25,0.3,0.4 --out "$out/cutoff" "$@"
ulps=999.9999999999999,1000.0,1000.0000000000001,1000.0000000000002,1000.0000000000003
beamcontact sweep "$cases/case_cg_paper.toml" --set beams.upper.material.density=$ulps --out "$out/roundoff" "$@"
# the same yardstick for the IPIP model of Figs. 8 and 9, and for the bundled benchmark
# (60 segments per element) that Fig. 7 compares with the solid and the peer codes
beamcontact sweep "$cases/case_ipip.toml" --set beams.upper.material.density=$ulps --out "$out/roundoff_ipip" "$@"
beamcontact sweep "$cases/case_cg.toml" --set beams.upper.material.density=$ulps --out "$out/roundoff_bundled" "$@"
python "$here/study_tables.py" "$out"
