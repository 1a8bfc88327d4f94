/* symmetry-merge - DAG chunk to minimal SSVDAG chunk; merge of sibling (SS)VDAG chunks. */
#include "voxdag.h"

#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"usage: symmetry-merge IN.dag -o OUT.ssvdag [options]\n"
	"       symmetry-merge --merge IN.ssvdag... -o OUT.ssvdag [--to-level A] [options]\n"
	"\n"
	"Builds the minimal SSVDAG of a DAG chunk: subtrees equal up to any of\n"
	"the 8 reflections (X, Y, Z mirrors and their combinations) become one\n"
	"node, referenced with a 3-bit reflection (SSVDAG paper, section 4.1).\n"
	"With --merge, builds the SSVDAG chunk of the cell containing the given\n"
	"DAG or SSVDAG chunks, reducing again from the leaves; applied up a\n"
	"reduction tree this yields the root chunk (level 0).\n"
	"With --group 48, subtrees equal under any of the 48 symmetries of the\n"
	"cube (the 6 axis permutations times the 8 reflections) become one\n"
	"node, referenced with a transform 0..47: an ssvdag48 chunk.\n"
	"Statistics go to OUT.ssvdag.stats.json.\n"
	"\n"
	"  -o, --output FILE       output chunk file (written atomically)\n"
	"  -M, --merge             merge the chunks of cells inside one cell:\n"
	"                          inputs of equal depth, no two overlapping\n"
	"  -t, --to-level A        with --merge: level of the output cell\n"
	"                          (default: one above the shallowest input)\n"
	"  -g, --group N           8 (default): the SSVDAG's reflections; 48:\n"
	"                          every cube symmetry (kind ssvdag48; merge\n"
	"                          takes dag, ssvdag and ssvdag48 chunks)\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -j, --threads N         worker threads (default: all cores) for the\n"
	"                          inner levels, alone or merging; same chunk\n"
	"                          for any N (bar its provenance)\n"
	"  -q, --quiet             no summary line on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O, budget), 2 usage.\n";

int main(int argc, char **argv)
{
	return vd_dag_stage_main(argc, argv, "symmetry-merge", VD_KIND_SSVDAG, usage);
}
