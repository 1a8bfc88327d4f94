/* svo-to-dag - SVO chunk to minimal SVDAG chunk; merge of sibling DAG chunks. */
#include "voxdag.h"

#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"usage: svo-to-dag IN.svo -o OUT.dag [options]\n"
	"       svo-to-dag --merge IN.dag... -o OUT.dag [--to-level A] [options]\n"
	"\n"
	"Builds the minimal SVDAG of an SVO chunk: bottom-up, level by level,\n"
	"identical subtrees become one node (Kaempe et al. 2013). With --merge,\n"
	"builds the DAG chunk of the cell containing the given DAG chunks,\n"
	"reducing again from the leaves so subtrees shared across chunks become\n"
	"one; applied up a reduction tree this yields the root chunk (level 0).\n"
	"Statistics go to OUT.dag.stats.json.\n"
	"\n"
	"  -o, --output FILE       output chunk file (written atomically)\n"
	"  -M, --merge             merge the chunks of cells inside one cell:\n"
	"                          inputs of equal depth, no two overlapping\n"
	"  -t, --to-level A        with --merge: level of the output cell\n"
	"                          (default: one above the shallowest input)\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -j, --threads N         worker threads (default: all cores) for the\n"
	"                          SVO bricks and the inner levels, merges too;\n"
	"                          same chunk for any N (bar its provenance)\n"
	"  -g, --group N           symmetry-merge only (the symmetry group);\n"
	"                          svo-to-dag refuses it: a plain SVDAG has none\n"
	"  -q, --quiet             no summary line on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O, budget), 2 usage.\n";

int main(int argc, char **argv)
{
	return vd_dag_stage_main(argc, argv, "svo-to-dag", VD_KIND_DAG, usage);
}
