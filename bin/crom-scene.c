/* crom-scene — build a rigid-body scene (a crom/mesh of bodies, joints and
 * penalty weights; lib/mesh/scene.h) from parameters: the pendulum, the
 * chains, the Klann linkage and the Stewart platform of Sharp et al. 2023
 * (§5.1, Table 1). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/err.h"
#include "base/parse.h"
#include "cli/cli.h"
#include "io/io.h"
#include "phys/scenes.h"

enum { O_LINKS = 'L' + 256, O_LENGTH, O_RADIUS, O_DENSITY, O_ANGLE, O_JOINTW, O_ORTHOW, O_LINK, O_RRADIUS, O_CONTACTW };

static const crom_opt scene_opts[] = {
    {"output", 'o', "OUT", "Write the scene to OUT (default: stdout, which must not be a terminal)."},
    {"links", O_LINKS, "N", "chain: number of links (default 24; 2 is the paper's mini chain)."},
    {"link", O_LINK, "KIND", "chain: ring (default: interlocked chain links held by contact penalties alone, Sharp et al.'s chain) or capsule (capsules joined end to end by point joints)."},
    {"length", O_LENGTH, "L", "pendulum: distance from the pivot to the bob's centre (default 1); chain: each capsule link's axis length (default 0.1), or each ring link's straight run (default 0.03), in metres."},
    {"radius", O_RADIUS, "R", "pendulum: the bob's radius (default 0.02); chain: each capsule link's radius (default 0.01), or each ring link's tube radius (default 0.005), in metres."},
    {"ring-radius", O_RRADIUS, "R", "chain of rings: the radius of each link's half circles in metres (default 0.02)."},
    {"contact-weight", O_CONTACTW, "W", "chain of rings: penalty weight of every contact point in N/m, energy 1/2 W min(phi, 0)^2 with phi the other link's signed distance (Sharp et al. eq. 9). Default 1e3 m g / r (m the chain's mass, r the tube radius)."},
    {"density", O_DENSITY, "RHO", "Density of every body in kg/m^3 (default 1000)."},
    {"angle", O_ANGLE, "DEG", "pendulum: the initial angle of the rod below the horizontal in degrees (default 90: hanging straight down); klann: the crank angle the linkage is assembled at (default 0). A chain starts horizontal along +x."},
    {"joint-weight", O_JOINTW, "W", "Penalty weight of every joint in N/m: energy 1/2 W |gap|^2 (Sharp et al. eq. 9). Default 1e4 m g / l (m the scene's mass, l the link length or pendulum length): a gap of 1e-4 l under the whole weight."},
    {"ortho-weight", O_ORTHOW, "W", "Weight of every body's orthogonality potential W |R^T R - I|_F^2 in J. Default 1e4 m_b g l (m_b the heaviest body)."},
    {NULL, 0, NULL, NULL}};

static const crom_cli_optgroup groups[] = {{"Options", scene_opts}, {NULL, NULL}};

static const crom_cli_doc doc = {
    "crom-scene",
    "build a rigid-body scene (bodies, penalty joints) for crom-fullsim",
    "crom-scene pendulum [--length L] [--radius R] [--angle DEG] [options] [-o OUT]\n"
    "crom-scene chain [--links N] [--link ring|capsule] [--length L] [--radius R] [options] [-o OUT]\n"
    "crom-scene klann [--length L] [--radius R] [--angle DEG] [options] [-o OUT]\n"
    "crom-scene stewart [--length L] [--radius R] [options] [-o OUT]",
    "Writes a crom/mesh holding a rigid-body scene (Sharp et al. 2023, section 5.1): each body "
    "is an analytic shape with a density, carried by four frame vertices whose lumped masses "
    "have its mass, centre and second moment exactly, so their affine motion is the body's [R|t] "
    "(12 coefficients) and an orthogonality potential W |R^T R - I|^2 keeps it rigid; joints "
    "are penalties 1/2 W |gap|^2 holding a point of one body to the same point of another, or to "
    "the world. Each body's four vertices form a region named after it, so crom-fullsim's "
    "--fix and --force act on bodies. y is up.\n\n"
    "pendulum: a sphere (region bob) whose centre is --length from a pivot at the origin, "
    "pinned there. chain: --links links along +x from the origin, the first pinned there by a "
    "ball joint (regions link0, link1, ...): rings (the paper's chain) alternately in the xy- "
    "and the xz-plane, each through the next's opening with a gap of half a tube radius, held "
    "together by contacts alone (every vertex of a link's surface against its neighbours' "
    "signed distance, both ways); or capsules of --length and --radius joined end to end.\n\n"
    "klann: the Klann linkage of the paper's Fig. 2 (one degree of freedom, in the xy-plane): "
    "a crank of --length (default 0.05) turning about the origin, a connecting rod held by a "
    "rocker, and a leg held by a second rocker, its end the foot; the bar lengths are the "
    "optimized Klann geometry of boim.com/Walkin8r scaled to the crank. Each moving link "
    "(regions crank, rod, rocker_b, rocker_d, leg) is a thin box of half width --radius "
    "(default 0.004); each revolute joint is two point joints --radius either side of the "
    "plane, the three ground pivots pinned to the world. The linkage is assembled at crank "
    "angle --angle (degrees, default 0).\n\n"
    "stewart: the Stewart platform of the paper's Fig. 2 (14 bodies, 168 DOF): a base pinned "
    "to the world, a platform --length (default 0.5) above it, and six telescoping legs, each "
    "a lower capsule hanging from the base by a ball joint and an upper capsule holding the "
    "platform by one, the upper sliding in the lower (two point-on-axis joints); --radius "
    "(default 0.02) is the legs'. With no actuators the legs slide freely: the platform keeps "
    "its six degrees of freedom (regions base, platform, leg0_lower, leg0_upper, ...).",
    groups,
    "crom-scene pendulum --length 1 --angle 85 -o pendulum.h5\n"
    "crom-scene klann -o klann.h5 && crom-export -o klann.png klann.h5\n"
    "crom-scene chain --links 24 -o chain.h5 && crom-fullsim chain.h5 --dt 0.005 --steps 200 -o chain-run.h5\n"
    "crom-scene chain --link capsule --links 8 --length 0.2 -o capsules.h5",
    "crom-fullsim(1), crom-info(1), crom-export(1), crom-mesh(1)"};

typedef struct {
    const char *kind, *out;
    crom_scenes_params p;
    int links_given, length_given, radius_given, angle_given, link_given, rradius_given, contact_given;
} args;

static int on_opt(void *ctx, int key, const char *v)
{
    args *a = ctx;
    long n;
    int rc;
    switch (key) {
    case 0:
        if (a->kind)
            return crom_err(CROM_EUSAGE, "unexpected operand '%s'", v);
        a->kind = v;
        return 0;
    case 'o': a->out = v; return 0;
    case O_LINKS:
        if ((rc = crom_parse_int(v, "--links", 1, 100000, &n)))
            return rc;
        a->p.links = (int)n;
        a->links_given = 1;
        return 0;
    case O_LENGTH: a->length_given = 1; return crom_parse_positive(v, "--length", &a->p.length);
    case O_RADIUS: a->radius_given = 1; return crom_parse_positive(v, "--radius", &a->p.radius);
    case O_DENSITY: return crom_parse_positive(v, "--density", &a->p.density);
    case O_ANGLE:
        a->angle_given = 1;
        if ((rc = crom_parse_range(v, "--angle", -180, 180, &a->p.angle)))
            return rc;
        a->p.angle *= M_PI / 180;
        return 0;
    case O_JOINTW: return crom_parse_positive(v, "--joint-weight", &a->p.joint_weight);
    case O_CONTACTW: a->contact_given = 1; return crom_parse_positive(v, "--contact-weight", &a->p.contact_weight);
    case O_RRADIUS: a->rradius_given = 1; return crom_parse_positive(v, "--ring-radius", &a->p.ring_radius);
    case O_LINK:
        a->link_given = 1;
        if (!strcmp(v, "ring") || !strcmp(v, "capsule")) {
            a->p.rings = v[0] == 'r';
            return 0;
        }
        return crom_err(CROM_EUSAGE, "--link: '%s' is not ring or capsule", v);
    case O_ORTHOW: return crom_parse_positive(v, "--ortho-weight", &a->p.ortho_weight);
    }
    return crom_err(CROM_EINTERNAL, "unhandled option");
}

static int run(crom_cli *cli, args *a)
{
    if (!a->kind)
        return crom_err(CROM_EUSAGE, "no scene given (pendulum, chain, klann, stewart)");
    int chain = !strcmp(a->kind, "chain"), klann = !strcmp(a->kind, "klann"), stewart = !strcmp(a->kind, "stewart");
    if (!chain && !klann && !stewart && strcmp(a->kind, "pendulum"))
        return crom_err(CROM_EUSAGE, "unknown scene '%s' (pendulum, chain, klann, stewart)", a->kind);
    if ((chain || stewart) && a->angle_given)
        return crom_err(CROM_EUSAGE, "--angle is for the pendulum and the Klann linkage");
    if (!chain && (a->links_given || a->link_given))
        return crom_err(CROM_EUSAGE, "--links and --link are for a chain");
    if ((!chain || !a->p.rings) && (a->rradius_given || a->contact_given))
        return crom_err(CROM_EUSAGE, "--ring-radius and --contact-weight are for a chain of rings");
    if (!a->length_given)
        a->p.length = stewart ? 0.5 : klann ? 0.05 : !chain ? 1 : a->p.rings ? 0.03 : 0.1;
    if (!a->radius_given)
        a->p.radius = stewart ? 0.02 : klann ? 0.004 : !chain ? 0.02 : a->p.rings ? 0.005 : 0.01;
    if (!chain && !klann && !stewart && !a->angle_given)
        a->p.angle = M_PI / 2;
    crom_mesh m;
    int rc = chain     ? crom_scenes_chain(&a->p, &m)
             : klann   ? crom_scenes_klann(&a->p, &m)
             : stewart ? crom_scenes_stewart(&a->p, &m)
                       : crom_scenes_pendulum(&a->p, &m);
    if (rc)
        return rc;
    if (cli->verbose) {
        const crom_scene *s = m.scene;
        double mass = 0;
        for (int b = 0; b < s->nb; b++)
            mass += s->bodies[b].density * crom_scene_body_volume(&s->bodies[b]);
        crom_cli_info(cli, "%s: %d bodies (%d DOF), %d joints of weight %.3g N/m, %d collision pairs of weight %.3g "
                           "N/m, orthogonality weight %.3g J, mass %.4g kg",
                      a->kind, s->nb, 12 * s->nb, s->nj, s->nj ? s->joints[0].weight : 0, s->np,
                      s->np ? s->pairs[0].weight : 0, s->ortho_weight, mass);
    }
    crom_out o;
    if (!(rc = crom_out_create(&o, a->out, CROM_MESH_SCHEMA, CROM_MESH_VERSION, cli->cmdline, NULL,
                               CROM_OUT_PLAIN))) {
        rc = crom_mesh_write(o.h5, &m);
        if (!rc)
            rc = crom_h5_set_str(o.h5, ".", "generator", a->kind);
        if (!rc)
            rc = crom_out_commit(&o);
        else
            crom_out_fail(&o);
    }
    crom_mesh_free(&m);
    return rc;
}

int main(int argc, char **argv)
{
    crom_cli cli;
    args a;
    memset(&a, 0, sizeof a);
    a.p.links = 24;
    a.p.rings = 1;
    a.p.ring_radius = 0.02;
    a.p.density = 1000;
    a.p.gravity = 9.81;
    crom_cli_parse(&cli, &doc, argc, argv, on_opt, &a);
    return crom_cli_exit(&cli, run(&cli, &a));
}
