/* ros2_dds: a Cyclone DDS participant speaking ROS 2's conventions, woken through an eventfd. */
#include "adapters/ros2/ros2_dds.h"

#include <ctype.h>
#include <errno.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include "core/err.h"

#define ROS2_MAX_READERS 64

typedef struct {
    char topic[256];            /* the DDS name, rt/... */
    char type[256];
} watched_t;

struct ros2_dds {
    dds_entity_t participant, publications;
    dds_listener_t *listener;
    int fd;
    watched_t watched[ROS2_MAX_READERS];
    int nwatched;
    uint64_t wrong_types;
    char wrong_topic[256], wrong_type[256];
};

static atomic_uint_fast64_t bad_cdr;

/* Cyclone warns once per sample it cannot deserialize; nothing else tells the application. */
static void on_log(void *user, const dds_log_data_t *m)
{
    if (m->priority == DDS_LC_WARNING && m->message && strstr(m->message, "deserialization"))
        atomic_fetch_add(&bad_cdr, 1);
}

uint64_t ros2_dds_take_bad_cdr(void) { return atomic_exchange(&bad_cdr, 0); }

/* Cyclone's thread: only wakes the marie loop, which takes the samples itself. */
static void on_data(dds_entity_t reader, void *arg)
{
    ros2_dds_t *d = arg;
    uint64_t one = 1;
    ssize_t n = write(d->fd, &one, sizeof one);
    (void)n;    /* EAGAIN: the counter is already far from zero, the loop will wake */
}

ros2_dds_t *ros2_dds_create(int domain_id, char *err, size_t errlen)
{
    if (domain_id < 0 || domain_id > 232) {
        snprintf(err, errlen, "domain id %d is outside 0-232", domain_id);
        return marie_fail_null(EINVAL);
    }
    ros2_dds_t *d = calloc(1, sizeof *d);
    if (!d)
        return NULL;
    d->fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (d->fd < 0) {
        snprintf(err, errlen, "eventfd: %s", strerror(errno));
        goto err_free;
    }
    dds_set_log_sink(on_log, NULL);
    dds_set_log_mask(DDS_LC_ERROR | DDS_LC_WARNING);
    d->participant = dds_create_participant((dds_domainid_t)domain_id, NULL, NULL);
    if (d->participant < 0) {
        snprintf(err, errlen, "DDS participant on domain %d: %s", domain_id, dds_strretcode(d->participant));
        errno = EIO;
        goto err_fd;
    }
    if (!(d->listener = dds_create_listener(d))) {
        snprintf(err, errlen, "DDS listener: out of memory");
        errno = ENOMEM;
        goto err_participant;
    }
    dds_lset_data_available(d->listener, on_data);
    d->publications = dds_create_reader(d->participant, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, NULL, d->listener);
    return d;

err_participant:
    MARIE_KEEP_ERRNO(dds_delete(d->participant));
err_fd:
    MARIE_KEEP_ERRNO(close(d->fd));
err_free:
    MARIE_KEEP_ERRNO(free(d));
    return NULL;
}

void ros2_dds_destroy(ros2_dds_t *d)
{
    if (!d)
        return;
    dds_delete(d->participant);
    dds_delete_listener(d->listener);
    close(d->fd);
    free(d);
}

int ros2_dds_fd(const ros2_dds_t *d) { return d->fd; }

void ros2_dds_drain(ros2_dds_t *d)
{
    uint64_t v;
    while (read(d->fd, &v, sizeof v) == sizeof v)
        ;
}

/* ROS 2's rules for a fully qualified name: alphanumerics and '_' between single '/'s, no
 * token starting with a digit, no trailing '/'. Private (~) and substitution ({}) names are not
 * offered: the system file names topics in full. */
int ros2_dds_topic_name(const char *ros_name, char *out, size_t len)
{
    const char *s = ros_name[0] == '/' ? ros_name + 1 : ros_name;
    if (!*s || s[strlen(s) - 1] == '/' || strlen(s) + 4 > len || strlen(s) > 200)
        return marie_fail(EINVAL);
    for (const char *p = s; *p; p++) {
        bool start = p == s || p[-1] == '/';
        if (*p == '/' ? start : !(isalnum((unsigned char)*p) || *p == '_') || (start && isdigit((unsigned char)*p)))
            return marie_fail(EINVAL);
    }
    snprintf(out, len, "rt/%s", s);
    return 0;
}

static dds_qos_t *qos_for(ros2_qos_t q, bool reader)
{
    dds_qos_t *qos = dds_create_qos();
    bool reliable = q == ROS2_QOS_DEFAULT || q == ROS2_QOS_LATCHED || q == ROS2_QOS_TF;
    int depth = q == ROS2_QOS_SENSOR ? 5 : q == ROS2_QOS_LATCHED || q == ROS2_QOS_CLOCK ? 1 : q == ROS2_QOS_TF ? 100 : 10;
    dds_qset_reliability(qos, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT, DDS_SECS(1));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, depth);
    dds_qset_durability(qos, q == ROS2_QOS_LATCHED ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
    /* marie writes plain CDR (XCDR1), as rmw_cyclonedds does; it reads XCDR2 too, which newer DDS
     * bindings may offer. */
    dds_qset_data_representation(qos, reader ? 2 : 1, (dds_data_representation_id_t[]){
                                     DDS_DATA_REPRESENTATION_XCDR1, DDS_DATA_REPRESENTATION_XCDR2});
    return qos;
}

static dds_entity_t make_topic(ros2_dds_t *d, const char *ros_name, const dds_topic_descriptor_t *desc, char *dds_name)
{
    if (ros2_dds_topic_name(ros_name, dds_name, 256) < 0)
        return DDS_RETCODE_BAD_PARAMETER;
    return dds_create_topic(d->participant, desc, dds_name, NULL, NULL);
}

dds_entity_t ros2_dds_writer(ros2_dds_t *d, const char *ros_name, const dds_topic_descriptor_t *desc, ros2_qos_t q)
{
    char name[256];
    dds_entity_t t = make_topic(d, ros_name, desc, name);
    if (t < 0)
        return t;
    dds_qos_t *qos = qos_for(q, false);
    dds_entity_t w = dds_create_writer(d->participant, t, qos, NULL);
    dds_delete_qos(qos);
    return w;
}

dds_entity_t ros2_dds_reader(ros2_dds_t *d, const char *ros_name, const dds_topic_descriptor_t *desc, ros2_qos_t q)
{
    char name[256];
    dds_entity_t t = make_topic(d, ros_name, desc, name);
    if (t < 0)
        return t;
    if (d->nwatched == ROS2_MAX_READERS)
        return DDS_RETCODE_OUT_OF_RESOURCES;
    dds_qos_t *qos = qos_for(q, true);
    dds_qset_ignorelocal(qos, DDS_IGNORELOCAL_PARTICIPANT);     /* never read back what we write */
    dds_entity_t r = dds_create_reader(d->participant, t, qos, d->listener);
    dds_delete_qos(qos);
    if (r >= 0) {
        watched_t *w = &d->watched[d->nwatched++];
        snprintf(w->topic, sizeof w->topic, "%s", name);
        snprintf(w->type, sizeof w->type, "%s", desc->m_typename);
    }
    return r;
}

static void check_publication(ros2_dds_t *d, const dds_builtintopic_endpoint_t *e)
{
    dds_guid_t mine;
    if (dds_get_guid(d->participant, &mine) == 0 && memcmp(&mine, &e->participant_key, sizeof mine) == 0)
        return;
    for (int i = 0; i < d->nwatched; i++) {
        if (strcmp(d->watched[i].topic, e->topic_name) == 0 && strcmp(d->watched[i].type, e->type_name) != 0) {
            d->wrong_types++;
            snprintf(d->wrong_topic, sizeof d->wrong_topic, "%s", e->topic_name);
            snprintf(d->wrong_type, sizeof d->wrong_type, "%s", e->type_name);
        }
    }
}

uint64_t ros2_dds_take_wrong_types(ros2_dds_t *d, char *topic, size_t len, char *type, size_t tlen)
{
    void *samples[8] = {NULL};
    dds_sample_info_t infos[8];
    int n;
    while (d->publications > 0 && (n = dds_take(d->publications, samples, infos, 8, 8)) > 0) {
        for (int i = 0; i < n; i++)
            if (infos[i].valid_data && infos[i].instance_state == DDS_IST_ALIVE)
                check_publication(d, samples[i]);
        dds_return_loan(d->publications, samples, n);
    }
    uint64_t w = d->wrong_types;
    d->wrong_types = 0;
    snprintf(topic, len, "%s", d->wrong_topic);
    snprintf(type, tlen, "%s", d->wrong_type);
    return w;
}
