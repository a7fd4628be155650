//! The seek history in C: a port of [`crate::history::History`]'s peek and step with
//! fixed-size rest stacks.

/// The history: a port of `crate::history::History::peek` / `step` with fixed-size rest stacks.
pub(super) const HISTORY_C: &str = r#"
static int sign_of(bias_real x) { return x > 0 ? 1 : (x < 0 ? -1 : 0); }

static void history_peek(const bias_model_history *h, bias_real time_s, bias_real target,
                         bias_model_features *f)
{
    bias_real source = h->started ? h->position : target;
    bias_real len = target - source;
    int move = sign_of(len);
    int change = move != 0 && h->direction != 0 && move != h->direction;
    int i;
    int has_od = 0, has_id = 0;
    bias_real od = 0, id = 0;
    f->seek_index = h->seeks;
    f->time_s = time_s;
    f->elapsed_s = h->started ? time_s - h->start_time : 0;
    f->dwell_s = h->started ? time_s - h->last_time : 0;
    f->source = source;
    f->target = target;
    f->seek_length = len;
    f->direction = move == 0 ? h->direction : move;
    f->direction_change = change;
    f->since_reversal = (change || h->direction == 0) ? fabs(len) : h->since_reversal + fabs(len);
    if (target > source) {
        if (h->n_below > 0) { has_od = 1; od = h->below[h->n_below - 1]; }
        for (i = h->n_above - 1; i >= 0; i--) {
            if (h->above[i] > target) { has_id = 1; id = h->above[i]; break; }
        }
    } else if (target < source) {
        for (i = h->n_below - 1; i >= 0; i--) {
            if (h->below[i] < target) { has_od = 1; od = h->below[i]; break; }
        }
        if (h->n_above > 0) { has_id = 1; id = h->above[h->n_above - 1]; }
    } else {
        if (h->n_below > 0) { has_od = 1; od = h->below[h->n_below - 1]; }
        if (h->n_above > 0) { has_id = 1; id = h->above[h->n_above - 1]; }
    }
    f->has_rest_od = has_od;
    f->rest_od = has_od ? target - od : 0;
    f->has_rest_id = has_id;
    f->rest_id = has_id ? id - target : 0;
}

/* Pushes p onto a stack of BIAS_MODEL_REST_CAP; when full, the bottom (farthest) is dropped. */
static void rest_push(bias_real *stack, int *n, bias_real p)
{
    if (*n == BIAS_MODEL_REST_CAP) {
        memmove(stack, stack + 1, (BIAS_MODEL_REST_CAP - 1) * sizeof *stack);
        *n -= 1;
    }
    stack[(*n)++] = p;
}

static void history_apply(bias_model_history *h, const bias_model_features *f)
{
    bias_real source = f->source, target = f->target;
    if (!h->started) {
        h->start_time = f->time_s;
    }
    if (target > source) {
        while (h->n_above > 0 && h->above[h->n_above - 1] <= target) h->n_above--;
        rest_push(h->below, &h->n_below, source);
    } else if (target < source) {
        while (h->n_below > 0 && h->below[h->n_below - 1] >= target) h->n_below--;
        rest_push(h->above, &h->n_above, source);
    }
    h->started = 1;
    h->position = target;
    h->last_time = f->time_s;
    h->seeks += 1;
    h->direction = f->direction;
    h->since_reversal = f->since_reversal;
}
"#;
