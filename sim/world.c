/* world: ODE bodies for a differential-drive robot on a plane among static wall boxes. */
#include "sim/world.h"

#include <errno.h>
#include <stdarg.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include <ode/ode.h>

#include "core/err.h"
#include "sim/rng.h"

/* Robot body, in the robot frame (x forward, y left, z up; origin on the ground under the
 * wheel axis). The wheels are spheres: one contact point straight under the hub, so the
 * effective track is exactly the hub spacing. */
#define CHASSIS_LX   0.50
#define CHASSIS_LY   0.34
#define CHASSIS_LZ   0.15
#define CHASSIS_Z    0.20
#define CHASSIS_MASS 18.0
#define WHEEL_MASS   1.0
#define CASTER_R     0.05
#define CASTER_X     0.20
#define LASER_Z      0.30
#define WALL_HEIGHT  1.0
#define WHEEL_FMAX   20.0       /* N m: enough for the ramp, limited so a wall wins */

struct sim_world {
    sim_params_t p;
    dWorldID world;
    dSpaceID walls;
    dGeomID ground;
    dJointGroupID contacts;
    dBodyID chassis, wheel[2];
    dGeomID chassis_geom, wheel_geom[2], caster_geom[2];
    dJointID hinge[2];
    dGeomID ray;
    occmap_t *map;              /* where the robot may be carried to */
    long nwalls;
    int64_t steps;
    int wall_contacts;
    bool estop;
    double target[2];           /* rad/s asked for */
    double setpoint[2];         /* rad/s after the ramp */
    double angle[2];            /* cumulative wheel angles */
    double speed[2];
    sim_rng_t rng;
};

static pthread_once_t ode_once = PTHREAD_ONCE_INIT;
static volatile long ode_messages;
/* ODE prints solver notes (a degenerate LCP while pushing into a wall) on stderr; they are
 * expected at a wall and only counted. */
static void ode_message(int num, const char *msg, va_list ap)
{
    (void)num; (void)msg; (void)ap;
    ode_messages++;
}

static void ode_init(void)
{
    dInitODE2(0);
    dSetMessageHandler(ode_message);
}

void sim_params_default(sim_params_t *p)
{
    *p = (sim_params_t)SIM_PARAMS_DEFAULTS;
}

static void place(dBodyID b, double x, double y, double z, double ox, double oy, double th)
{
    double c = cos(th), s = sin(th);
    dBodySetPosition(b, ox + c * x - s * y, oy + s * x + c * y, z);
    dMatrix3 R;
    dRFromAxisAndAngle(R, 0, 0, 1, th);
    dBodySetRotation(b, R);
}

/* The chassis keeps its proportions; robot_radius (the system file's robot.radius, shared with
 * the planner and behaviours) is the circle around it. */
static double body_scale(const sim_params_t *p)
{
    return p->robot_radius > 0 ? p->robot_radius / hypot(CHASSIS_LX / 2, CHASSIS_LY / 2) : 1.0;
}

void sim_world_footprint(const sim_params_t *p, double *lx, double *ly)
{
    *lx = CHASSIS_LX * body_scale(p);
    *ly = CHASSIS_LY * body_scale(p);
}

int sim_world_teleport(sim_world_t *w, double x, double y, double theta)
{
    double lx, ly;
    sim_world_footprint(&w->p, &lx, &ly);
    if (!isfinite(x) || !isfinite(y) || !isfinite(theta) || !occmap_footprint_clear(w->map, x, y, theta, lx, ly))
        return marie_fail(EINVAL);
    place(w->chassis, 0, 0, CHASSIS_Z, x, y, theta);
    for (int k = 0; k < 2; k++)
        place(w->wheel[k], 0, (k == 0 ? 1 : -1) * w->p.track / 2, w->p.wheel_radius, x, y, theta);
    dBodySetLinearVel(w->chassis, 0, 0, 0);
    dBodySetAngularVel(w->chassis, 0, 0, 0);
    for (int k = 0; k < 2; k++) {
        dBodySetLinearVel(w->wheel[k], 0, 0, 0);
        dBodySetAngularVel(w->wheel[k], 0, 0, 0);
        const dReal *hp = dBodyGetPosition(w->wheel[k]);
        dJointSetHingeAnchor(w->hinge[k], hp[0], hp[1], hp[2]);
        dJointSetHingeAxis(w->hinge[k], -sin(theta), cos(theta), 0);
    }
    return 0;
}

sim_world_t *sim_world_create(const occmap_t *map, const sim_params_t *p)
{
    pthread_once(&ode_once, ode_init);
    dAllocateODEDataForThread(dAllocateMaskAll);
    if (p->step <= 0 || p->wheel_radius <= 0 || p->track <= 0 || p->laser_beams < 1 ||
        p->laser_max <= p->laser_min || p->ticks_per_rev <= 0)
        return marie_fail_null(EINVAL);
    sim_world_t *w = calloc(1, sizeof(*w));
    if (!w)
        return NULL;
    w->p = *p;
    w->map = occmap_from_cells(map->width, map->height, map->resolution, map->origin_x, map->origin_y, 0, map->cells);
    if (!w->map) {
        free(w);
        return NULL;
    }
    sim_rng_seed(&w->rng, p->seed);
    /* ODE's own generator is process-wide; reseed it so runs repeat (dWorldStep is exact and
     * does not use it, but contact generation may). */
    dRandSetSeed((unsigned long)p->seed);
    w->world = dWorldCreate();
    dWorldSetGravity(w->world, 0, 0, -9.81);
    dWorldSetERP(w->world, 0.2);
    dWorldSetCFM(w->world, 1e-6);
    w->walls = dHashSpaceCreate(0);
    w->contacts = dJointGroupCreate(0);
    w->ground = dCreatePlane(0, 0, 0, 1, 0);

    /* Walls: one static box per merged rectangle (the grid is aligned with the map frame). */
    sim_rect_t *rects = NULL;
    long nr = sim_walls_rects(map, &rects);
    if (nr < 0) {
        sim_world_destroy(w);
        return marie_fail_null(ENOMEM);
    }
    double res = map->resolution;
    for (long k = 0; k < nr; k++) {
        double cx, cy;
        /* centre of the rectangle = centre between its corner cells */
        double x0, y0, x1, y1;
        occmap_cell_center(map, rects[k].i, rects[k].j, &x0, &y0);
        occmap_cell_center(map, rects[k].i + rects[k].w - 1, rects[k].j + rects[k].h - 1, &x1, &y1);
        cx = (x0 + x1) / 2;
        cy = (y0 + y1) / 2;
        dGeomID g = dCreateBox(w->walls, rects[k].w * res, rects[k].h * res, WALL_HEIGHT);
        dGeomSetPosition(g, cx, cy, WALL_HEIGHT / 2);
    }
    w->nwalls = nr;
    free(rects);

    /* Robot. */
    double ox = p->start_x, oy = p->start_y, th = p->start_theta, r = p->wheel_radius;
    double lx, ly, caster_x = CASTER_X * body_scale(p);
    sim_world_footprint(p, &lx, &ly);
    dMass m;
    w->chassis = dBodyCreate(w->world);
    dMassSetBoxTotal(&m, CHASSIS_MASS, lx, ly, CHASSIS_LZ);
    dBodySetMass(w->chassis, &m);
    place(w->chassis, 0, 0, CHASSIS_Z, ox, oy, th);
    w->chassis_geom = dCreateBox(0, lx, ly, CHASSIS_LZ);
    dGeomSetBody(w->chassis_geom, w->chassis);
    for (int k = 0; k < 2; k++) {
        /* casters: frictionless spheres fixed under the chassis, front and back */
        w->caster_geom[k] = dCreateSphere(0, CASTER_R);
        dGeomSetBody(w->caster_geom[k], w->chassis);
        dGeomSetOffsetPosition(w->caster_geom[k], k ? -caster_x : caster_x, 0, CASTER_R - CHASSIS_Z);
    }
    for (int k = 0; k < 2; k++) {
        double y = (k == 0 ? 1 : -1) * p->track / 2;   /* 0 = left (+y), 1 = right */
        w->wheel[k] = dBodyCreate(w->world);
        dMassSetSphereTotal(&m, WHEEL_MASS, r);
        dBodySetMass(w->wheel[k], &m);
        place(w->wheel[k], 0, y, r, ox, oy, th);
        w->wheel_geom[k] = dCreateSphere(0, r);
        dGeomSetBody(w->wheel_geom[k], w->wheel[k]);
        /* body1 = wheel, body2 = chassis: the hinge rate is the wheel's spin about +y,
         * which rolls the robot forward. */
        w->hinge[k] = dJointCreateHinge(w->world, 0);
        dJointAttach(w->hinge[k], w->wheel[k], w->chassis);
        const dReal *hp = dBodyGetPosition(w->wheel[k]);
        dJointSetHingeAnchor(w->hinge[k], hp[0], hp[1], hp[2]);
        dJointSetHingeAxis(w->hinge[k], -sin(th), cos(th), 0);
        dJointSetHingeParam(w->hinge[k], dParamFMax, WHEEL_FMAX);
        dJointSetHingeParam(w->hinge[k], dParamVel, 0);
    }
    w->ray = dCreateRay(0, p->laser_max);
    return w;
}

void sim_world_destroy(sim_world_t *w)
{
    if (!w)
        return;
    if (w->ray)
        dGeomDestroy(w->ray);
    for (int k = 0; k < 2; k++) {
        if (w->wheel_geom[k])
            dGeomDestroy(w->wheel_geom[k]);
        if (w->caster_geom[k])
            dGeomDestroy(w->caster_geom[k]);
    }
    if (w->chassis_geom)
        dGeomDestroy(w->chassis_geom);
    if (w->ground)
        dGeomDestroy(w->ground);
    if (w->walls)
        dSpaceDestroy(w->walls);        /* destroys the wall boxes too */
    if (w->contacts)
        dJointGroupDestroy(w->contacts);
    if (w->world)
        dWorldDestroy(w->world);
    occmap_destroy(w->map);
    free(w);
}

void sim_world_set_wheels(sim_world_t *w, double left, double right)
{
    double m = w->p.max_wheel_speed;
    w->target[0] = left > m ? m : left < -m ? -m : left;
    w->target[1] = right > m ? m : right < -m ? -m : right;
}

void sim_world_set_velocity(sim_world_t *w, double v, double omega)
{
    double r = w->p.wheel_radius, t = w->p.track;
    double wl = (v - omega * t / 2) / r, wr = (v + omega * t / 2) / r;
    /* Scale both wheels together so an over-fast command keeps its curvature. */
    double m = fmax(fabs(wl), fabs(wr));
    if (m > w->p.max_wheel_speed) {
        wl *= w->p.max_wheel_speed / m;
        wr *= w->p.max_wheel_speed / m;
    }
    sim_world_set_wheels(w, wl, wr);
}

void sim_world_set_estop(sim_world_t *w, bool pressed)
{
    w->estop = pressed;
}

typedef struct {
    sim_world_t *w;
    dGeomID robot_geom;
    double mu;
} collide_ctx_t;

static void add_contacts(sim_world_t *w, dGeomID a, dGeomID b, double mu, int *count)
{
    dContactGeom cg[4];
    int n = dCollide(a, b, 4, cg, sizeof(cg[0]));
    for (int i = 0; i < n; i++) {
        dContact c;
        memset(&c, 0, sizeof(c));
        c.geom = cg[i];
        c.surface.mode = dContactSoftERP | dContactSoftCFM | (mu > 0 ? dContactApprox1 : 0);
        c.surface.mu = mu;
        c.surface.soft_erp = 0.5;
        c.surface.soft_cfm = 1e-5;
        dJointID j = dJointCreateContact(w->world, w->contacts, &c);
        dJointAttach(j, dGeomGetBody(a), dGeomGetBody(b));
    }
    if (count)
        *count += n;
}

static void wall_cb(void *data, dGeomID o1, dGeomID o2)
{
    collide_ctx_t *ctx = data;
    /* o1 is the robot geom, o2 a wall box */
    add_contacts(ctx->w, o1, o2, ctx->mu, &ctx->w->wall_contacts);
}

void sim_world_step(sim_world_t *w)
{
    double dt = w->p.step;
    /* The drives' velocity ramp. */
    double dmax = (w->estop ? fmax(w->p.estop_decel, w->p.accel) : w->p.accel) / w->p.wheel_radius * dt;
    for (int k = 0; k < 2; k++) {
        double goal = w->estop ? 0.0 : w->target[k];
        double d = goal - w->setpoint[k];
        w->setpoint[k] += d > dmax ? dmax : d < -dmax ? -dmax : d;
        dJointSetHingeParam(w->hinge[k], dParamVel, w->setpoint[k]);
    }
    w->wall_contacts = 0;
    dGeomID robot[5] = { w->wheel_geom[0], w->wheel_geom[1], w->caster_geom[0], w->caster_geom[1],
                         w->chassis_geom };
    double ground_mu[5] = { 1.0, 1.0, 0.0, 0.0, 0.3 };
    for (int k = 0; k < 5; k++) {
        add_contacts(w, robot[k], w->ground, ground_mu[k], NULL);
        collide_ctx_t ctx = { w, robot[k], 0.2 };
        dSpaceCollide2(robot[k], (dGeomID)w->walls, &ctx, wall_cb);
    }
    dWorldStep(w->world, dt);
    dJointGroupEmpty(w->contacts);
    for (int k = 0; k < 2; k++) {
        w->speed[k] = dJointGetHingeAngleRate(w->hinge[k]);
        w->angle[k] += w->speed[k] * dt;
    }
    w->steps++;
}

int64_t sim_world_time_us(const sim_world_t *w)
{
    return (int64_t)llround(w->steps * w->p.step * 1e6);
}

int64_t sim_world_steps(const sim_world_t *w)
{
    return w->steps;
}

double sim_world_step_s(const sim_world_t *w)
{
    return w->p.step;
}

void sim_world_pose(const sim_world_t *w, double *x, double *y, double *theta)
{
    const dReal *pos = dBodyGetPosition(w->chassis);
    const dReal *R = dBodyGetRotation(w->chassis);
    *x = pos[0];
    *y = pos[1];
    *theta = atan2(R[4], R[0]);
}

void sim_world_velocity(const sim_world_t *w, double *v, double *omega)
{
    double x, y, th;
    sim_world_pose(w, &x, &y, &th);
    const dReal *lv = dBodyGetLinearVel(w->chassis);
    const dReal *av = dBodyGetAngularVel(w->chassis);
    *v = lv[0] * cos(th) + lv[1] * sin(th);
    *omega = av[2];
}

int sim_world_wall_contacts(const sim_world_t *w)
{
    return w->wall_contacts;
}

long sim_world_wall_boxes(const sim_world_t *w)
{
    return w->nwalls;
}

typedef struct {
    double best;
} ray_ctx_t;

static void ray_cb(void *data, dGeomID o1, dGeomID o2)
{
    ray_ctx_t *ctx = data;
    dContactGeom cg;
    if (dCollide(o1, o2, 1, &cg, sizeof(cg)) > 0 && cg.depth < ctx->best)
        ctx->best = cg.depth;   /* for a ray, depth is the distance from its start */
}

static int laser(sim_world_t *w, float *ranges, int n, bool noisy)
{
    const sim_params_t *p = &w->p;
    if (n > p->laser_beams)
        n = p->laser_beams;
    double x, y, th;
    sim_world_pose(w, &x, &y, &th);
    double lx = x + p->laser_x * cos(th), ly = y + p->laser_x * sin(th);
    double inc = p->laser_beams > 1 ? p->laser_fov / (p->laser_beams - 1) : 0;
    for (int i = 0; i < n; i++) {
        double a = th - p->laser_fov / 2 + i * inc;
        dGeomRaySet(w->ray, lx, ly, LASER_Z, cos(a), sin(a), 0);
        ray_ctx_t ctx = { p->laser_max };
        dSpaceCollide2(w->ray, (dGeomID)w->walls, &ctx, ray_cb);
        double r = ctx.best;
        if (r < p->laser_max && noisy) {
            r += p->laser_noise * sim_rng_gauss(&w->rng);
            if (r < p->laser_min)
                r = p->laser_min;
            if (r >= p->laser_max)
                r = p->laser_max;
        }
        ranges[i] = (float)r;
    }
    return n;
}

int sim_world_laser(sim_world_t *w, float *ranges, int n)
{
    return laser(w, ranges, n, true);
}

int sim_world_laser_exact(sim_world_t *w, float *ranges, int n)
{
    return laser(w, ranges, n, false);
}

double sim_world_gyro(sim_world_t *w)
{
    const dReal *av = dBodyGetAngularVel(w->chassis);
    return av[2] + w->p.gyro_bias + w->p.gyro_noise * sim_rng_gauss(&w->rng);
}

void sim_world_wheels(const sim_world_t *w, double *la, double *ra, double *ls, double *rs)
{
    if (la) *la = w->angle[0];
    if (ra) *ra = w->angle[1];
    if (ls) *ls = w->speed[0];
    if (rs) *rs = w->speed[1];
}

static int32_t ticks(double angle, int32_t tpr)
{
    int64_t t = (int64_t)floor(angle / (2 * M_PI) * tpr);
    return (int32_t)(uint32_t)(uint64_t)t;      /* wraps like a 32-bit counter */
}

void sim_world_encoders(const sim_world_t *w, int32_t *left, int32_t *right)
{
    *left = ticks(w->angle[0], w->p.ticks_per_rev);
    *right = ticks(w->angle[1], w->p.ticks_per_rev);
}

const sim_params_t *sim_world_params(const sim_world_t *w)
{
    return &w->p;
}
