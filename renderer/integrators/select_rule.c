/* select_rule.c: how the tile selection (select.c) chooses each tile's estimator from the
 * statistics its samples left, the pilot's and the epochs' (rd_select_stats, in two halves of
 * each tile): the variance a sample and its lower bound, the prior of the non-zero probability,
 * the trial that evidence of unequal size calls for, the halves and the image's prediction where
 * they disagree, the tiles no sample has lit, and the rule that weighs variance against cost
 * over the image. select.c draws the samples, counts their cost and calls this at the pilot's
 * end and at every epoch (rd_select_choose_tiles).
 *
 * The variance. Per channel, the squared deviations from each pixel's own mean, pooled over the
 * tile's pixels (the image's squared error sums the pixels' variances). It is bounded below by
 * Cauchy-Schwarz: a non-negative X with mean mu that is non-zero with probability p has
 * E[X^2] >= mu^2 / p, so Var X >= mu^2 (1/p - 1). The bound is what sees a narrow beam that
 * delta's path never finds: its samples are all zero, sample variance 0, but mu, the mean of
 * the two estimators' means (both unbiased for the tile's mean), is not, and p falls as the
 * zeros pile up. p is the posterior mean of the tile's non-zero probability under a Beta prior
 * of two pseudo-samples, Beta(2 pbar, 2 (1 - pbar)), centred on the estimator's non-zero
 * fraction over the image's lit tiles (empirical Bayes),
 *     p = (non-zero + 2 pbar) / (n + 2),   pbar = (sum of non-zero + 1) / (sum of n + 2)
 * over the tiles where either estimator saw a non-zero sample. Until session 22 it was
 * Laplace's rule (pbar = 1/2), which in a tile of 128 zeros puts p at 1/130 whatever the rest
 * of the image shows: on hard-narrow-spot `delta`'s samples are non-zero once in a thousand
 * (39 of the pilot's 38400 over the whole image), so its variance there was read as 14x the
 * marcher's where it is about 150x, and 85% of the samples went to `delta`
 * (docs/guided-marching.md, "The equiangular sample"). A tile's own non-zero samples outweigh the prior as they come. The
 * sums include the epochs' samples, so the tiles already given to an estimator weigh most in
 * its pbar (not measured: a pbar from the pilot's counts alone would avoid it).
 *
 * A dim tile's prior (session 48). The image's pbar is mostly the bright tiles' fraction: in a
 * dim tile every estimator finds light less often, and an estimator that saw nothing there
 * (plain `delta` beside a narrow beam's faint glow) was read as far less heavy-tailed than it
 * is. On hard-narrow-spot such a tile went to plain `delta` at the pilot and one of its samples
 * found the beam: a quarter of the image's squared error in one pixel. So an estimator's prior
 * centre in a tile is pbar times how dim the tile is to the other estimators: the hits they saw
 * there over the hits the image's fractions expect from their samples, (sum of non-zero + 1) /
 * (sum of n pbar + 1) over the others (one pseudo-hit each side), capped at 1. The estimator's
 * own count is left out: its zeros are in p already, and a tile bright to the others where it
 * alone saw nothing is not dim. The scale only ever makes a bound stronger, for an estimator
 * with few hits in a tile the others find dimmer than the image's lit tiles on average. A tile
 * no estimator has lit has mu = 0 and no bound either way.
 *
 * Evidence of unequal size. At an epoch the tile's current estimator has the image's thousands of
 * samples and the other only its pilot's hundred or so. A heavy tail is seen in proportion to
 * the samples drawn, so the comparison favours the estimator with fewer: where both carry the
 * same rare firefly (the lens caustic's path through the glass to the small light, which the
 * method's paths find no more often than delta's), delta's thousands show it and the method's
 * hundred do not, and the tile went to the method at 3x the cost for no less variance
 * (docs/benchmarks.md, "Session 13"). So a tile moves to the other estimator at once only when
 * that estimator's samples in the tile are at least 1 / RD_SELECT_TRIAL_RATIO of the current
 * one's (4, the epochs' own growth: an epoch's choice never rests on evidence more lopsided
 * than one epoch's growth); else the tile goes on trial: for the next epoch half its pixels (a
 * checkerboard) take the other estimator, whose samples then grow as fast as the current
 * one's, and the next epoch decides by the rule alone, on evidence of comparable size (a trial
 * from the epoch at 16 ends at 64 with about 26 samples a pixel against 42: 2 + 24 against
 * 2 + 16 + 24, the pilot's and the image's). Where the other estimator is truly better (a
 * narrow beam that delta's paths rarely find), the trial shows it and the tile moves one epoch
 * later; where it only looked better, the trial shows its tail too.
 *
 * Off the biased beams at once (session 66). A tile that leaves the beams while the image reads
 * their bias (bias_ratio above its margin, "The beams' bias" below, and the rule weighed it: an
 * end known) moves without a trial, even where its halves disagree (the other half's wish to
 * keep the beams is their variance's, which the bias outweighs in the image's choice or else in
 * the cheaper of the two), and to whichever estimator the rule wants, not only one on trial. A
 * trial would keep the beams on half its pixels until the samples a pixel are 4x what they are,
 * and over those n samples the bias adds to a pixel's sum coherently, n^2 beta^2, where their
 * noise adds n V: the later samples dilute it only as their share of the mean grows. A move that
 * a tail in delta's few samples made look right costs variance, and the next epoch can move the
 * tile back, at once where the beams' samples are then at least a quarter of the other's (they
 * usually are after one epoch: a tile can swing between the two, each move on the rule's
 * figures with the bias counted). On cloud at 60 s the bias shows by the epoch at 64, when 89
 * tiles went on trial to delta's path, and the beams' samples of those tiles' first 256 a pixel
 * stayed in the image: `guided` made 0.43-0.89x plain `delta` in six rounds (median 0.72),
 * 0.80-1.13x (median 0.99) with the moves made at once (docs/benchmarks.md "Session 66").
 * Moves onto the beams, and off them where no bias is read, go on trial as above.
 *
 * Replication (session 27). The rule takes in each tile the estimator whose figures came out
 * least, and where they are noisy that is in part the one whose noise ran low: a costlier
 * estimator then takes a tile for a variance gain that was noise, and pays its cost for sure.
 * Heavy tails make this common, and the pool spreads one tile's outlier over nine. On
 * hard-dense-block (`delta` with "tiles", 160x120), a pilot of 256 samples a pixel instead of
 * SEL_SPP (4096 a tile and estimator; a scratch switch, not kept) read delta's V over its V
 * with the strategy at 0.08 to 73 across the lit tiles, where over the whole image it is 1.36
 * (0.230 against 0.169 a sample, 512 spp); the rule gave 30-41 tiles the strategy at 1.6x the
 * counted cost (1.9x the time), and "tiles" made 0.85x plain `delta`'s efficiency where every
 * tile forced to delta's path made 0.956x (a debug switch, not kept). One of those tiles kept
 * the strategy with its own 128 delta samples at V 0.0013 against the strategy's 27.7: its
 * neighbour's delta pilot read 1604. On hard-narrow-spot one pilot firefly of the strategy held
 * nine tiles on guided-unbiased's paths at 2.7x its cost (docs/benchmarks.md "Session 26").
 *
 * So each tile's samples are kept in two halves, by 2x2 blocks of pixels in a checkerboard
 * (half_stats: each half holds half of a tile's pilot pixels and half of a trial's squares),
 * the rule runs on each half alone, and a tile takes the estimator both halves want; where they
 * differ, the cheaper of the two by the counted cost of all the tile's samples, pooled as the
 * rule's figures are (cost is counted, so nearly exact; the noise is in the variance; an exact
 * tie goes to the lower index, as in `least`). A real gain shows in both halves, one firefly in
 * one. A move the halves do not agree on goes on trial first, whatever the evidence's size (but
 * off the beams while their bias is read: "Off the biased beams at once" above): one
 * half's word is weak evidence, and taken at once it can strand a tile. On a 24x16 view of thin
 * fog (the compare tests' scene, sigma_t 0.25, seed 2, "tiles") one firefly of the strategy's
 * own in one half at the first epoch sent all six tiles to plain delta for good, where the
 * strategy is 1.8x plain delta's efficiency; with the trial, six seeds of six keep the strategy
 * (as without the halves). The prior pbar and the trial's evidence are all the tile's samples'.
 * A tile of at most 2x2 pixels (at the image's right and bottom edges) lies in one half: the
 * other half's figures for it are zero and its choice is the half that has samples.
 *
 * Measured in docs/benchmarks.md "Session 27" (the dense block's "tiles" 0.851x -> 0.913x).
 *
 * Where the halves disagree, the image decides (session 40). Until then the cheaper of the two
 * took such a tile, and on hard-dense-block that was most of the lit tiles at the first epochs
 * (the halves of 45, 50 and 64 of about 75 disagreed at the pilot and the epochs at 4 and 16),
 * where `delta`'s heavy tail shows only at thousands of samples a tile: its variance a sample
 * read 0.0005 from a tile's pilot, 0.13 from 1152 samples, about 1.0 from 10^4, against the
 * method's 0.014-0.09 at 8-12x the cost; the tiles moved late, and a pixel's mean keeps the
 * samples drawn before a move (docs/benchmarks.md "Session 39"). Pooled over the lit tiles the
 * tail shows at once: a scratch print of every tile's statistics (guided-unbiased, 160x120, seed
 * 8) read `delta`'s variance a sample 1.16 from the pilot's 9472 samples and 0.69 from the
 * 594048 of the epochs up to 256, where the median tile read 0.015 and 0.41; the method's pooled
 * 0.127 and 0.22. So where the halves disagree, each estimator's variance in the tile is read as
 * the rest of the image predicts it, mu^2 r, with mu the tile's mean (as in the bound above) and
 *     r = sum of dev2 / sum of (dof mu^2) over the lit tiles outside the tile's 3x3,
 * the estimator's relative variance pooled over the image but the 3x3 tiles whose samples the
 * tile's own figures pool (so the prediction is evidence besides the halves': one tile's
 * firefly, which the pooling spreads into one half of its neighbours, is not in their r; and a
 * one-tile image keeps the halves' rule exactly), and the rule on those figures (not pooled
 * over 3x3 tiles, which would bring the neighbours' predictions back; the tiles' own costs,
 * pooled as always) picks between the halves' two (if it wants neither,
 * or an estimator has no prediction, r 0, the cheaper, as before). The move still goes on trial
 * first (as above, but off the biased beams), and where the halves agree nothing changes.
 * Measured (guided-unbiased's dense block 1.33x, the calibration scenes 0.98-1.21x), and the
 * forms tried and not kept (r everywhere as a prior, by empirical Bayes, as a veto; weaker
 * pooling): docs/benchmarks.md "Session 40", "41" and "53".
 *
 * Tiles no sample has lit (session 42). Where no estimator has drawn a non-zero sample in a
 * tile or its neighbours, every variance the rule reads there is 0 and it gives the tile the
 * cheapest estimator: of delta's two paths, the one without the strategy. On hard-narrow-spot
 * that is the faint glow around the beam (over the lit tiles plain delta's samples are non-zero
 * once in a thousand, above): a tile that saw nothing in the pilot took plain delta, drew its
 * first firefly after 64-1024 samples a pixel, and moved
 * to the strategy at the next epoch, but its pixels keep the firefly. `delta` with "tiles",
 * 1024 spp, 160x120, seeds 1-3: its squared error 1.42x that of `true` (the strategy
 * everywhere) at equal samples, 98% of the excess in 15 of the 300 tiles; of the 8 largest
 * (seed 1), 5 were unlit at the pilot. So a tile no sample has lit, where the rule gives it
 * plain delta and delta has two paths (sel->paths: the third estimator, or delta's own
 * "tiles"), takes the path the rule picks for the whole image from the pilot's samples summed
 * over the lit tiles (image_path; the pilot draws the same number of each estimator in every
 * tile, so the sums compare like with like). It moves there at once, without a trial: there is
 * no evidence to weigh. Where the image prefers plain delta (the dense block, default, cloud,
 * hetero-forward) nothing changes; where it prefers the strategy (the narrow spot, the window
 * beam, homogeneous, glass-fog) a tile that stays dark pays the strategy's set-up on flights
 * that find nothing. Measured in docs/benchmarks.md "Session 42" ("tiles"' squared error
 * 1.71e-6 -> 1.49e-6 at 1024 spp, `true`'s 1.45e-6).
 *
 * The bound's tile mean with the beams (session 58). The mean of the estimators' means is
 * unbiased, but one estimator's firefly lifts it, and with it every other estimator's bound:
 * near the narrow spot's apex `delta`'s and guided-unbiased's paths each drew one (tile means
 * 0.73 against the others' 0.12), and the marcher's and delta-with-the-strategy's bounds read
 * 9-76 a tile against their own samples' 0.014-0.033 a sample (their zeros are the tile's
 * pixels that see no light): four tiles stayed on the beams, 1.3% of the samples and 2/3 of
 * the time (docs/guided-marching.md "The beams beside the marcher"). The beams' own mean has no
 * such tail (every sample gathers the photons about the whole ray: never zero, variance a
 * sample 0.023 there), so where the selection holds the beams their tile mean is the centre of
 * every bound (bound_centre). It carries the kernel's bias, which a bound can bear: the bound is
 * a floor under a variance, not an estimate of the image. The median of the means, tried in
 * session 57, vanished where most estimators saw only zeros (beam.json: 2.05x plain `delta`
 * against 17.3 in one round); the beams see the light wherever a photon does. Measured at 10 s,
 * four rounds, `guided` with march.beams over plain `delta` before -> after (docs/benchmarks.md
 * "Session 58"): the narrow spot 170 (5.7-326) -> 445 (143-803), beam 4.9 (0.087-17.6) -> 21.3
 * (0.66-23.6), default 2.65 -> 2.98, homogeneous 5.12 -> 5.27; the dense block 0.86 (0.20-1.36)
 * -> 0.60 (0.23-1.23), paired 0.61-1.17, its error in a few tiles' outliers either way and the
 * beams' share the same (21%); without the beams nothing changes.
 *
 * A mean that lags the beams' (session 59). The Cauchy-Schwarz bound reads a tail from the zeros
 * an estimator draws; an estimator whose samples are never zero but mostly far too small shows
 * none, and its sample variance is its body's alone. On hard-dense-block the marcher's samples
 * at the block's dim edge are all non-zero, and its tile means read 0.42 of the reference's at
 * the median over the lit tiles, the beams' 1.00 (`guided` with march.beams, 10 s, seed 951, the
 * selection's trace): one tile took the marcher at the epoch at 4 on a variance of 0.0001 a
 * sample at a mean of 0.0005 where the beams' read 0.006, and one of its samples then put 2.5 in
 * a pixel of 0.019, 67% of the render's squared error. For a non-negative X of mean mu whose n
 * samples show a mean m, the part d = mu - m is held by draws none of the n were, of some
 * probability q, so Var X >= d^2 (1/q - 1), and after n misses q = 1/(n + 2) (Laplace's rule,
 * as the bound's p without a prior): Var X >= d^2 (n + 1). Where the selection holds the beams,
 * their mean is the mu, as for the bound's centre; they carry the kernel's bias, so only the part
 * of d beyond half their mean counts (SEL_LAG_SLACK: a bias up to a doubling of the tile's mean,
 * a bound, not fitted), less three standard errors of the two means (SEL_LAG_SIGMA; the beams'
 * counted whole, where half of it would do: a margin), so that a lag at the noise's size floors
 * nothing and the floor grows from zero as the lag clears it. A half's 64 pilot samples of the
 * beams read a dim tile's mean to ~30%, so the lag is read over the tile's 3x3 neighbourhood, the
 * rule's pooling (lag_floor: each mean the mean of the tiles' means, so that a trial's or a
 * choice's samples weigh no tile more), and it floors the rule's figure (pooled, or the image's
 * prediction where the halves disagree, which reads all the tile's samples; not image_path's
 * figure for the tiles no sample has lit, where there is no mean to lag). This is the other
 * reading of the gap select.c's head tried as the beams' bias ("A consistent method"), which
 * lost where the beams were right: there delta's pilot mean was low for a tail it had not drawn.
 * The slack bounds the bias it allows; where the beams are more than twice the truth (their
 * kernel's blur into a dark tile beside a bright one) the floor holds the others off, more so as
 * their samples grow (a risk, not a loss seen in the rounds measured). Without the beams nothing
 * changes: the mean of the means is lifted by one estimator's firefly, and every other estimator
 * would lag it. Measured at 10 s, four rounds, gB over plain `delta` (docs/benchmarks.md "Session
 * 59"): the dense block 1.02 (0.65-1.46) -> 1.30 (0.94-1.66); default, beam, sphere-in-fog,
 * cloud and the lens caustic within their rounds' spread. At 60 s the dense block's beams still
 * lose to the marcher without them (their passes' shared noise, which their spread does not show;
 * read into the rule in session 60 and not kept: the tiles it moved went on trial to estimators
 * whose tails their pilots had not shown, docs/guided-marching.md "The passes' shared
 * noise, read and not kept").
 *
 * The samples the image holds (session 61). A pixel's mean keeps every sample drawn before an
 * epoch, and the rule used to weigh each estimator's variance a sample as if all the pixel's
 * samples were to be its own. On smoke-vdb (`guided` with march.beams, 10 s) the beams went on
 * trial in 85 tiles at the pilot and 87 at the epoch at 16, on figures that say they win there
 * in the long run (V 0.000139 a sample at a counted cost of 456, against delta's 0.0172 at 11.5):
 * but a beams square's 16 earlier samples of delta outweigh 48 of the beams' 40 to 1 in its
 * variance, and at ~75 us a sample the beams reach 54-232 samples a pixel in the 10 s against
 * `guided`'s 830. gB made 0.33-0.77x plain `delta` there (docs/benchmarks.md "Session 60"). So at
 * an epoch the rule minimises what the image's squared error will be when the render ends: with
 * n0 samples a pixel so far, whose variances sum to P over the pixels (each estimator's image
 * samples in a tile times its variance a sample as the figures read it: the past weighed as the
 * samples to come are; the samples' own spread, below the figures' floors where those bind, would
 * make the past look better than the same estimator's future and could turn the cost's weight
 * negative, favouring costlier estimators late in a render), and R the time left (the
 * render's time left over its image's so far, rd_render_ctx.epoch_ahead, times the image's
 * counted cost so far), a choice with figure sums V and C draws a = R / C more samples a pixel
 * and leaves
 *     (P + a V) / (n0 + a)^2,
 * summed over the pixels (past_of, objective). A long time left (a V >> P, a >> n0) gives back
 * V C / R, the product below; so does the pilot (no image samples: P = n0 = 0), and so does a
 * render with no end known (rd_select_epoch's `end` NULL, as the unit tests' stand-ins). A move
 * that pays only in the long run is made only if the run is long: the horizon is the render's
 * end, not the next epoch (the next epoch's n1 = 4 n0 as the horizon would keep a past of one
 * estimator for good, each epoch seeing the same 4x). The time left is taken at the image's mean
 * pace so far. A render that ends at a sample count draws its left samples a pixel whatever they
 * cost, so there the rule minimises the error at the end times the render's time, (P + left V)
 * (T0 + left C) with T0 the image's counted cost so far (the error's (n0 + left)^2 is the same for
 * every choice); at a deadline a costlier choice draws fewer samples, which the deadline's form
 * weighs. The choices then depend on the render's budget and, at a deadline, on the clock: a
 * render of 64 samples is no longer the first 64 of one of 256 with the same seed (each is
 * unbiased, and several ranks read one figure: render.c takes the largest). Only `guided`'s
 * selection is given the render's end (guided.c): guided-unbiased's, given it, lost 30% of its
 * efficiency on hard-dense-block in two rounds at 10 s (1.43 -> 1.05, 1.74 -> 1.21 plain `delta`;
 * fewer tiles on trial to its paths at the epoch at 64, 2 against 30 in seed 1031, though the
 * objective's weights there, printed by a scratch build, were within 6% of the product's: not
 * understood; docs/guided-marching.md "The samples the image holds"), and `delta`'s "tiles" was
 * not measured; both weigh the samples to come alone, as before.
 *
 * The beams' bias (session 64). The beams are consistent, not unbiased: their kernel averages
 * the in-scattered light over balls of radius r, which the passes shrink slowly (the mean r^2
 * over n passes falls as n^(-2/7): bake/passes.c), so more samples leave a pixel's bias as it
 * is. The figures held variance and cost only, and on cloud at 60 s the beams, on 31% of the
 * samples, left a squared bias of 1.0e-5 a pixel, 89% of the image's error, where `guided`
 * without them made 2.2x the efficiency (docs/benchmarks.md "Session 63"). So every beams sample
 * also reads its picks with balls of half the volume, radius r / sqrt 2 (rd_march_beam_estimate's
 * gap, rd_thread.beam_gap): where the bias grows as r^2 the small balls carry half of it and twice
 * the gap estimates it (Richardson's extrapolation). On cloud, from renders of the beams alone at
 * r and at r / sqrt 2 (128 spp, two seeds), the squared bias a pixel read 4.8e-6 from the gaps
 * against 7.1e-6 from the two renders' errors (docs/guided-marching.md "The beams' bias read from
 * their own samples").
 *
 * A blur's bias changes sign across an edge of the light, inside a tile too, so what counts is
 * each pixel's squared gap, not a tile's mean gap squared (on cloud the tiles' squared bias was
 * a quarter of the pixels'). It is read per pixel, from all the pixel's image samples so far
 * (rd_select.gaps; the pilot's read pass 1 only and give none), as the product of the mean gaps
 * of its samples on the odd and on the even photon passes: the two share no photons but pass
 * 1's, which set every pass's radii, so the product is a nearly unbiased estimate of the squared
 * gap; the pixels weigh by their samples and count once they hold passes of all four classes mod
 * 4 (bias_fold). Each sample's gap is read at pass 1's
 * radius (over its pass's radius_scale: the bias taken to grow as r, below), and the ratio at the
 * radius of the pass then (times radius_scale^2). (A pixel's squared mean gap
 * less its samples' spread over n read high: the samples of one pass share its photons' noise,
 * which their spread does not show; on hard-dense-block `guided` fell from 2.9x to 0.79x `delta`
 * in a 60-s round.) The products are noisy, and the weight of the bias grows with the samples to
 * come (below), so a tile's own pixels (or its 3x3 tiles') could not tell cloud's bias from none
 * at 60 s: per tile, the dense block lost 2.9x -> 0.68x and 2.0x -> 0.54x `delta` in two 60-s
 * rounds, on noise. So the rule reads one figure for the image, the ratio of the beams' squared
 * bias to their variance a sample over all their pixels (bias_ratio), less SEL_BIAS_SIGMA
 * standard errors and not below 0, and gives each tile B = that ratio times the beams' variance
 * figure there: a bias that shows over the whole image is counted where the beams' noise is.
 * The standard error is the noise's alone: each pixel keeps its gaps by pass class mod 4 and
 * reads, beside its product, the same four cross products (even x odd classes) with two signs
 * turned, which have the product's variance where the gap is 0 and mean 0 whatever the bias
 * (bias_fold); it is summed over each tile before it is squared (the pixels near each other share
 * the photons their balls hold, so their noise is shared), with the covariances of the tiles
 * that touch (bias_ratio).
 * A first form took the spread of the tiles' sums of products instead, which counts the bias's
 * own spread over the tiles as noise too.
 * Session 64 read it per record instead (an epoch's samples of a pixel, each record's product
 * one draw, the records taken as independent): the early epochs' records, products of means of
 * few samples, weighed as much as the last's, and the standard error read low; cloud's ratio
 * swung between seeds (0.016 and 0.041 at the epoch at 256), and so did its beams' tiles (89 and
 * 4) and `guided`'s efficiency (0.40x and 0.80x `delta` at 60 s). Read from all of a pixel's
 * samples, with the standard error from the tiles' spread (the first form of session 65),
 * cloud's ratio read 0.0090 +- 0.0013 and 0.0075 +- 0.0010 at that epoch (the same two seeds,
 * at the radius then and with the factor 4 below), the dense block's 0.0020 +- 0.0039.
 *
 * The squared bias is RD_SELECT_BIAS_PER_GAP2 = (1 - 1/sqrt 2)^-2 = 11.66 squared gaps, not 4:
 * where the bias grows as r^p the gap is (1 - 2^(-p/2)) of it, and p is 1, not 2, where the
 * radiance has a corner within the ball, at a lit face or a shadow's edge, where a blur's bias
 * lives (session 64's test: twice the gap read 0.59 of the bias at an edge of the light, which is
 * p = 1's 1 - 1/sqrt 2 = 0.29 of it; the Richardson check above read 0.68 of cloud's squared
 * bias with the factor 4). Taking p = 2 reads the edges' squared bias 2.9x low, p = 1 the smooth
 * parts' 2.9x high, and where the beams' error is their bias a reading low costs more: with the
 * factor 4 the rule kept the beams in 85-89 of cloud's tiles to the end at 60 s.
 * The half ball's term follows the big one's pick (half_ball_term): with the small ball's
 * indicator at the pick instead, the gaps were 2.5x noisier over cloud's image (session 64).
 *
 * The objective counts B as a pixel's mean carries it when the render ends: with a samples a
 * pixel still to come of n0 + a, the samples to come make a / (n0 + a) of the mean, and a tile
 * whose past samples were the beams' for a share s of them carries their bias too, so beams to
 * come raise the mean's squared bias by (a^2 + 2 a n0 s) beta^2 / (n0 + a)^2 (the tile's B is
 * scaled by 1 + 2 n0 s / a: bias_figures; the past's own square is the same whatever the
 * choice). At a deadline the objective adds w B with w = (a / (n0 + a))^2, and a tile's figure
 * in the fixed point is V + lambda C + w (n0 + a)^2 / a B (w's derivative over the variance's,
 * a / (n0 + a)^2; bias_weight), which is a B at the image's pace; with a sample count it adds
 * left^2 B to P + left V. w is taken at the image's pace so far (ahead n0 samples to come: past_of), not at the
 * choices' own a: as a function of their cost it rewarded costly choices for drawing fewer
 * samples (a smaller share of the mean, so less of its bias), and with a large B the fixed
 * point's lambda went negative (hard-dense-block at 60 s: 77% of the samples to the beams where a
 * noisy B counted). The pilot has no end known and weighs no bias. Measured in docs/benchmarks.md
 * "Session 64".
 *
 * The rule. At equal time the image's MSE is (sum_k V_k)(sum_k C_k) / time for the choices
 * m_k of the tiles k, so the best choices minimise the product. Its stationary point is where
 * every tile takes the m minimising V_k,m + lambda C_k,m with lambda = sum V / sum C of the
 * choices themselves (d(VC) = C dV + V dC = 0): the fixed point is found by iterating from
 * each tile's own best V C, a few rounds; then single flips that lower the product itself are
 * made until none does (rd_select_choose). With the image's samples (above) the same holds for
 * (P + a V) / (n0 + a)^2, whose lambda is (2 P + (a - n0) V) / (C (n0 + a)) (slope).
 *
 * The shares of the samples and their weights (settings.adaptive): select_share.c.
 *
 * Fixed shares (session 71). With "pilot"'s shares each tile k draws a share s_k of the sample
 * indices, set at the pilot's choice and kept whatever estimator it takes later (select_share.c,
 * "Pilot shares"). Past the pilot a tile's choice no longer sets its share, so the adaptive
 * rule's sum of sqrt(V C) (which assumes it does) is not the error at equal time: a sample index
 * costs the image sum C_k s_k and its error is sum V_k / s_k, and the rule is the product's
 * (above) on those figures (choose). Where the pilot gave a tile a small share, the estimator's
 * variance there weighs 1 / s_k and its cost s_k: a costlier, quieter estimator pays there where
 * its own sqrt(V C) would lose. With the image's samples, P, n0 and T0 count in sample indices
 * too (past_of). The choices still read only samples past, so the image stays unbiased. */
#include "integrators/rd_select.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SEL_ROUNDS 32 /* fixed-point rounds at most */
#define SEL_TIE 1e-9  /* relative margin below which the method does not beat delta */
#define SEL_LAG_SLACK 0.5 /* the beams' mean may be twice the truth (their kernel's bias) */
#define SEL_LAG_SIGMA 3.0 /* standard errors of the two means taken off a lag: its noise */
#define SEL_BIAS_SIGMA 3.0 /* standard errors taken off the beams' squared bias ratio: its noise */
#define SEL_BIAS_TILES 8.0 /* tiles at least with the beams' products: a standard error of fewer is noise */

/* Channel c of a tile's mean, from its m statistics tile[0 .. m-1]: estimator centre's mean
 * where centre >= 0 has samples (the beams: see the head, "The bound's tile mean with the
 * beams"), else the mean of the estimators' means (all unbiased for it), over those with
 * samples; 0 if none has. */
static double tile_mean(const rd_select_stats *tile, int m, int c, int centre)
{
    if (centre >= 0 && tile[centre].n > 0.0) return tile[centre].sum[c] / tile[centre].n;
    double mu = 0.0;
    int k = 0;
    for (int j = 0; j < m; j++)
        if (tile[j].n > 0.0) mu += tile[j].sum[c] / tile[j].n, k++;
    return k ? mu / k : 0.0;
}

/* The estimator whose mean is the bound's tile mean: the beams where the selection holds them
 * (last), else -1 (the mean of all the estimators' means). */
static int bound_centre(const rd_select *sel)
{
    return sel->n > 0 && sel->kind[sel->n - 1] == RD_SEL_BEAMS ? sel->n - 1 : -1;
}

/* The per-sample variance of estimator e (0 .. m-1) in a tile whose m statistics are
 * tile[0 .. m-1] (mean over RGB): the pooled sample variance, or with r > 0 the image's
 * prediction mu^2 r (see the head, "Where the halves disagree"), bounded below by Cauchy-Schwarz
 * with mu the tile's mean (tile_mean, with the centre `centre`) and the non-zero
 * probability p from the tile's count and a prior centred on pbar, e's fraction over the lit
 * tiles, times the tile's dimness (see the head; figures). */
static double tile_variance(const rd_select_stats *tile, int m, int e, double pbar, double r, int centre)
{
    const rd_select_stats *st = &tile[e];
    if (!(st->n > 0.0)) return 0.0;
    double p = (st->nonzero + 2.0 * pbar) / (st->n + 2.0), v = 0.0;
    for (int c = 0; c < 3; c++) {
        double mu = tile_mean(tile, m, c, centre);
        double sv = r > 0.0 ? r * mu * mu : st->dof > 0.0 ? st->dev2[c] / st->dof : 0.0;
        v += fmax(sv, mu > 0.0 ? mu * mu * (1.0 / p - 1.0) : 0.0);
    }
    return v / 3.0;
}

/* The estimator of a tile (m of them, figures f[0 .. m-1]) that minimises f: a later estimator
 * must beat the best so far by more than rounding, so a tie goes to the lower index (delta; a
 * tile the camera sees no medium in costs every estimator the same, summed over different
 * numbers of samples). */
static uint8_t least(const double *f, int m)
{
    int b = 0;
    for (int e = 1; e < m; e++)
        if (f[e] < f[b] * (1.0 - SEL_TIE)) b = e;
    return (uint8_t)b;
}

/* The rule's objective for figure sums V, C and B (see the head, "The rule", "The samples the
 * image holds" and "The beams' bias"): V C; with the image's samples so far and a deadline, the
 * image's squared error then (times the pixels), (P + a V) / (n0 + a)^2 + w B with a = R / C the
 * samples a pixel draws in the time left and w the bias's weight (rd_select_past.w); with a sample
 * count, that error times the render's time, (P + left V + left^2 B)(T0 + left C) (up to the
 * constant (n0 + left)^2). */
static double objective(double V, double C, double B, const rd_select_past *past)
{
    if (!past) return V * C;
    const double l = past->left;
    if (l > 0.0) return (past->P + l * V + l * l * B) * (past->T0 + l * C);
    if (!(C > 0.0)) return 0.0; /* (a figure of no cost draws samples without end: no error) */
    double a = past->R / C;
    return (past->P + a * V) / ((past->n0 + a) * (past->n0 + a)) + past->w * B;
}

/* The weight lambda of cost against variance at which the objective is stationary (its
 * derivative in C over its derivative in V): V / C for the product; with a deadline
 * (2 P + (a - n0) V) / (C (n0 + a)), which is V / C when nothing is past (P = n0 = 0) or the
 * time left is long (a V >> P and a >> n0), and which is negative where a < n0 and the samples
 * to come would be noisier a sample than 2 P / (n0 - a): fewer of them then make a better mean;
 * with a sample count (P + left V + left^2 B) / (T0 + left C), never negative (the samples are
 * drawn whatever they cost). */
static double slope(double V, double C, double B, const rd_select_past *past)
{
    if (!past) return V / C;
    const double l = past->left;
    if (l > 0.0) return (past->P + l * V + l * l * B) / (past->T0 + l * C);
    double a = past->R / C;
    return (2.0 * past->P + (a - past->n0) * V) / (C * (past->n0 + a));
}

/* The weight of the squared bias against the variance in the fixed point (their derivatives'
 * ratio): with a sample count left, with a deadline w (n0 + a)^2 / a (past->w); 0 with no end
 * known. */
static double bias_weight(double C, const rd_select_past *past)
{
    if (!past) return 0.0;
    if (past->left > 0.0) return past->left;
    if (!(C > 0.0 && past->R > 0.0)) return 0.0;
    double a = past->R / C;
    return past->w * (past->n0 + a) * (past->n0 + a) / a;
}

void rd_select_choose(const double *var, const double *cost, const double *bias, int n, int m,
                      const rd_select_past *past, uint8_t *choice)
{
#define BIAS(i) (bias ? bias[i] : 0.0)
    double f[RD_SEL_MAX];
    for (int k = 0; k < n; k++) { /* start: each tile's own best V C */
        for (int e = 0; e < m; e++) f[e] = var[m * k + e] * cost[m * k + e];
        choice[k] = least(f, m);
    }
    for (int round = 0; round < SEL_ROUNDS; round++) {
        double V = 0.0, C = 0.0, B = 0.0;
        for (int k = 0; k < n; k++) V += var[m * k + choice[k]], C += cost[m * k + choice[k]], B += BIAS(m * k + choice[k]);
        if (!(C > 0.0)) return;
        double lambda = slope(V, C, B, past), mu = bias_weight(C, past);
        int changed = 0;
        for (int k = 0; k < n; k++) {
            for (int e = 0; e < m; e++) f[e] = var[m * k + e] + lambda * cost[m * k + e] + mu * BIAS(m * k + e);
            uint8_t u = least(f, m);
            changed += u != choice[k];
            choice[k] = u;
        }
        if (!changed) break;
    }
    /* The fixed point is stationary for the linearised objective, but a tile whose move trades
     * variance for cost can still lower the objective itself (the cross term dV dC < 0, and the
     * past's curvature): move such tiles, one at a time, to the first other estimator that
     * lowers it, until no single move helps. */
    double V = 0.0, C = 0.0, B = 0.0;
    for (int k = 0; k < n; k++) V += var[m * k + choice[k]], C += cost[m * k + choice[k]], B += BIAS(m * k + choice[k]);
    for (int round = 0, changed = 1; changed && round < SEL_ROUNDS; round++) {
        changed = 0;
        double F = objective(V, C, B, past);
        for (int k = 0; k < n; k++)
            for (int e = 0; e < m; e++) {
                int o = choice[k];
                if (e == o) continue;
                double V2 = V - var[m * k + o] + var[m * k + e], C2 = C - cost[m * k + o] + cost[m * k + e];
                double B2 = B - BIAS(m * k + o) + BIAS(m * k + e);
                double F2 = objective(V2, C2, B2, past);
                if (F2 < F * (1.0 - 1e-12)) {
                    choice[k] = (uint8_t)e;
                    V = V2, C = C2, B = B2, F = F2;
                    changed = 1;
                }
            }
    }
#undef BIAS
}

void rd_select_choose_adaptive(const double *var, const double *cost, const double *bias, int n, int m,
                               const rd_select_past *past, uint8_t *choice)
{
#define BIAS(i) (bias ? bias[i] : 0.0)
    double f[RD_SEL_MAX];
    for (int k = 0; k < n; k++) { /* each tile's own best V C: the rule with no end known */
        for (int e = 0; e < m; e++) f[e] = sqrt(var[m * k + e] * cost[m * k + e]);
        choice[k] = least(f, m);
    }
    if (!past || !(past->R > 0.0) || past->left > 0.0 || !bias) return;
    /* A deadline: E = S^2 / R + B with S = sum sqrt(V C), the variance and the squared bias of a
     * mean of the samples to come (the past's not read: both would take the same factor);
     * d E = (2 S / R) d sqrt(V C) + d B, so each tile takes the least of (2 S / R) sqrt(V C) + B
     * at the fixed point of S. */
    const double R = past->R;
    for (int round = 0; round < SEL_ROUNDS; round++) {
        double S = 0.0;
        for (int k = 0; k < n; k++) S += sqrt(var[m * k + choice[k]] * cost[m * k + choice[k]]);
        int changed = 0;
        for (int k = 0; k < n; k++) {
            for (int e = 0; e < m; e++) f[e] = 2.0 * S / R * sqrt(var[m * k + e] * cost[m * k + e]) + BIAS(m * k + e);
            uint8_t u = least(f, m);
            changed += u != choice[k];
            choice[k] = u;
        }
        if (!changed) break;
    }
    /* then single moves that lower E itself, until none does (as rd_select_choose) */
    double S = 0.0, B = 0.0;
    for (int k = 0; k < n; k++) S += sqrt(var[m * k + choice[k]] * cost[m * k + choice[k]]), B += BIAS(m * k + choice[k]);
    for (int round = 0, changed = 1; changed && round < SEL_ROUNDS; round++) {
        changed = 0;
        double F = S * S / R + B;
        for (int k = 0; k < n; k++)
            for (int e = 0; e < m; e++) {
                int o = choice[k];
                if (e == o) continue;
                double S2 = S - sqrt(var[m * k + o] * cost[m * k + o]) + sqrt(var[m * k + e] * cost[m * k + e]);
                double B2 = B - BIAS(m * k + o) + BIAS(m * k + e), F2 = S2 * S2 / R + B2;
                if (F2 < F * (1.0 - 1e-12)) {
                    choice[k] = (uint8_t)e;
                    S = S2, B = B2, F = F2;
                    changed = 1;
                }
            }
    }
#undef BIAS
}

/* Each tile's figures a[m k + e] (one per estimator) replaced by the mean over its 3x3
 * neighbourhood (clipped at the image's edge), in tmp's room of m nx ny doubles. A tile's own
 * pilot has 16 pixels x SEL_SPP (select.c) samples (8 pixels in each half), and delta's variance is
 * heavy-tailed (a rare path that finds the light): alone, one tile's estimate swings the choice
 * from seed to seed; nine tiles' pooled steady it, at the price of a one-tile blur of the map,
 * and of one tile's outlier moving nine tiles' figures (which the halves check: the head,
 * "Replication"). */
static void pool(double *a, double *tmp, int nx, int ny, int m)
{
    size_t n = (size_t)nx * ny;
    memcpy(tmp, a, (size_t)m * n * sizeof *tmp);
    for (int ty = 0; ty < ny; ty++)
        for (int tx = 0; tx < nx; tx++) {
            size_t k = (size_t)ty * nx + tx;
            double sv[RD_SEL_MAX] = {0};
            int cnt = 0;
            for (int y = ty - 1; y <= ty + 1; y++)
                for (int x = tx - 1; x <= tx + 1; x++) {
                    if (x < 0 || y < 0 || x >= nx || y >= ny) continue;
                    size_t j = (size_t)y * nx + x;
                    for (int e = 0; e < m; e++) sv[e] += tmp[m * j + e];
                    cnt++;
                }
            for (int e = 0; e < m; e++) a[m * k + e] = sv[e] / cnt;
        }
}

/* The squared standard error of channel c of the mean of statistics st (0 without a deviation). */
static double mean_se2(const rd_select_stats *st, int c)
{
    return st->dof > 0.0 && st->n > 0.0 ? st->dev2[c] / st->dof / st->n : 0.0;
}

/* The lag bound (see the head, "A mean that lags the beams'"): each tile's figure var[m k + e]
 * raised to pixels x the variance a sample that the lag of e's mean behind the beams' (estimator
 * centre) implies over the tile's 3x3 neighbourhood of statistics st. Per channel, with each
 * mean the mean of the tiles' means over the neighbours where both have samples (the tiles
 * alike, whatever samples each holds), the part d of the beams' mean mu (1 - SEL_LAG_SLACK) that
 * e's samples have not shown, less SEL_LAG_SIGMA standard errors of the two means, is held by a
 * tail none of e's n samples there drew, with probability q = 1 / (n + 2) (Laplace's, after n
 * misses): d^2 (1/q - 1) = d^2 (n + 1). */
static void lag_floor(const rd_select *sel, const rd_select_stats *st, int centre, double *var)
{
    int nx = sel->tiles_x, ny = sel->tiles_y, m = sel->n;
    for (int k = 0; k < nx * ny; k++) {
        int tx = k % nx, ty = k / nx;
        const double pixels = rd_select_tile_pixels(sel, tx, ty);
        for (int e = 0; e < m; e++) {
            if (e == centre) continue;
            double samples = 0.0, tiles = 0.0, me[3] = {0}, mc[3] = {0}, se2[3] = {0};
            for (int y = ty - 1; y <= ty + 1; y++)
                for (int x = tx - 1; x <= tx + 1; x++) {
                    if (x < 0 || y < 0 || x >= nx || y >= ny) continue;
                    const rd_select_stats *a = &st[m * (y * nx + x) + e], *b = &st[m * (y * nx + x) + centre];
                    if (!(a->n > 0.0 && b->n > 0.0)) continue;
                    samples += a->n, tiles += 1.0;
                    for (int c = 0; c < 3; c++)
                        me[c] += a->sum[c] / a->n, mc[c] += b->sum[c] / b->n, se2[c] += mean_se2(a, c) + mean_se2(b, c);
                }
            if (!(tiles > 0.0)) continue;
            double v = 0.0;
            for (int c = 0; c < 3; c++) {
                double d = (mc[c] * (1.0 - SEL_LAG_SLACK) - me[c] - SEL_LAG_SIGMA * sqrt(se2[c])) / tiles;
                if (d > 0.0) v += d * d * (samples + 1.0);
            }
            var[m * k + e] = fmax(var[m * k + e], pixels * v / 3.0);
        }
    }
}

/* "pilot"'s shares past the pilot (shares without weights, set at the pilot's choice), [m k + e]
 * the same for every e of tile k; NULL where the shares follow the choice or there are none. */
static const float *fixed_shares(const rd_select *sel)
{
    return sel->share && !sel->weight && !sel->blocks && sel->choices > 0 ? sel->share : NULL;
}

/* The rule for the tiles' figures var and cost (as rd_select_choose's) into choice: the adaptive
 * rule where the shares follow the choice; where they are fixed (fixed_shares), the product's
 * rule on each tile's error and time a sample index, V / s and C s (the head, "Fixed shares"),
 * var and cost scaled in place; without shares the product's rule on the figures as they are. */
static void choose(const rd_select *sel, double *var, double *cost, const double *bias, const rd_select_past *p,
                   uint8_t *choice)
{
    const int n = sel->tiles_x * sel->tiles_y, m = sel->n;
    const float *fix = fixed_shares(sel);
    if (sel->share && !fix) {
        rd_select_choose_adaptive(var, cost, bias, n, m, p, choice);
        return;
    }
    for (int k = 0; fix && k < n; k++)
        for (int e = 0; e < m; e++) var[m * k + e] /= fix[m * k], cost[m * k + e] *= fix[m * k];
    rd_select_choose(var, cost, bias, n, m, p, choice);
}

/* The image's samples so far (see the head, "The samples the image holds"), for the rule on
 * figures var (one set of m per tile, as figures() gives them) from the statistics all (a tile's
 * two halves): P, the sum over the tiles of each estimator's image samples there times its
 * variance a sample as var reads it (var[m k + j] / pixels: the same figures, bounds and pooling
 * as the samples to come are weighed by), n0 the image's samples a pixel, T0 their counted cost,
 * and the end: R = end->ahead T0 (the time left, in the costs' units) or end->left. 0 (no past to
 * weigh: the rule on the samples to come alone) where the image holds no sample (the pilot) or
 * the render has no end known (end NULL or both 0). With fixed shares (fixed_shares) in sample
 * indices: P as N0 sum V / s and n0 as the held samples over the pixels' shares, which is N0
 * but for the first RD_SHARE_FIRST samples and the epoch at 4, drawn at share 1 (only `guided`
 * with "pilot" reaches this: guided-unbiased's and delta's selections know no end). */
static int past_of(const rd_select *sel, const rd_select_stats *all, const double *var, const rd_select_end *end,
                   rd_select_past *past)
{
    const int by_time = end && end->ahead > 0.0 && isfinite(end->ahead), by_samples = end && end->left > 0.0;
    if (!by_time && !by_samples) return 0;
    int nx = sel->tiles_x, n = nx * sel->tiles_y, m = sel->n;
    const float *fix = fixed_shares(sel);
    double P = 0.0, held = 0.0, T0 = 0.0, drawn = 0.0; /* drawn: the pixels times their shares */
    for (int k = 0; k < n; k++) {
        const double pixels = rd_select_tile_pixels(sel, k % nx, k / nx), sh = fix ? fix[m * k] : 1.0;
        drawn += pixels * sh;
        for (int j = 0; j < m; j++) {
            const rd_select_stats *s = &all[m * k + j];
            /* fixed shares: in sample indices, N0 V / s for a tile's s N0 samples a pixel (above) */
            P += fix ? s->image_n * var[m * k + j] / (pixels * sh * sh) : s->image_n * var[m * k + j] / pixels;
            held += s->image_n, T0 += s->image_cost;
        }
    }
    if (!(held > 0.0 && T0 > 0.0 && drawn > 0.0)) return 0;
    past->P = P, past->n0 = held / (fix ? drawn : (double)sel->width * sel->height), past->T0 = T0;
    past->R = by_time ? end->ahead * T0 : 0.0, past->left = by_time ? 0.0 : end->left;
    /* at the pace so far the image draws ahead n0 samples a pixel more: a share ahead / (1 + ahead) */
    past->w = by_time ? (end->ahead / (1.0 + end->ahead)) * (end->ahead / (1.0 + end->ahead)) : 0.0;
    return 1;
}

/* The rule's figures from statistics st ([m k + e], one set of m per tile): each tile's V and C
 * (as sums over its pixels, which is what the image's error and time add up), pooled over 3x3
 * tiles (pool), with each estimator's non-zero prior centred on pbar[e] times the tile's dimness
 * to the other estimators (see the head, "A dim tile's prior"); with r (unless NULL) each tile's
 * V is the prediction from the estimator's relative variance beyond the tile's 3x3, r[m k + e],
 * not pooled (pooling would bring back the neighbours' predictions, which hold the tile's own
 * samples). var or cost may be NULL. */
static void figures(const rd_select *sel, const rd_select_stats *st, const double *pbar, const double *r,
                    double *var, double *cost, double *tmp)
{
    const int centre = bound_centre(sel);
    int nx = sel->tiles_x, ny = sel->tiles_y, n = nx * ny, m = sel->n;
    for (int k = 0; k < n; k++) {
        int tx = k % nx, ty = k / nx;
        const double pixels = rd_select_tile_pixels(sel, tx, ty);
        /* The hits the tile's estimators saw, and those the image's fractions expect of them */
        double z = 0.0, x = 0.0;
        for (int e = 0; e < m; e++) z += st[m * k + e].nonzero, x += st[m * k + e].n * pbar[e];
        for (int e = 0; e < m; e++) {
            const rd_select_stats *s = &st[m * k + e];
            /* e's prior centre scaled by how dim the others find the tile (see the head, "A dim
             * tile's prior"): its own zeros are in p already */
            const double dim = fmin(1.0, (z - s->nonzero + 1.0) / (x - s->n * pbar[e] + 1.0));
            if (var) var[m * k + e] = pixels * tile_variance(&st[m * k], m, e, pbar[e] * dim, r ? r[m * k + e] : 0.0, centre);
            if (cost) cost[m * k + e] = s->n > 0.0 ? pixels * s->cost / s->n : 0.0;
        }
    }
    if (var && !r) pool(var, tmp, nx, ny, m); /* (r's predictions are pooled over the image already) */
    if (var && centre >= 0) lag_floor(sel, st, centre, var);
    if (cost) pool(cost, tmp, nx, ny, m);
}

/* For each tile k and estimator e, e's relative variance pooled over the lit tiles of statistics
 * st (all of the tiles' samples) outside the 3x3 tiles k's figures are pooled over,
 * r[m k + e] = sum dev2 / sum (dof mu^2) over them, mu per channel as in tile_variance; 0 where
 * they have no deviation of e's (see the head, "Where the halves disagree"). num and den: room
 * for m n doubles each. */
static void pooled_relative_variance(const rd_select *sel, const rd_select_stats *st, double *r, double *num,
                                     double *den)
{
    const int centre = bound_centre(sel);
    int n = sel->tiles_x * sel->tiles_y, m = sel->n;
    double N[RD_SEL_MAX] = {0}, D[RD_SEL_MAX] = {0};
    for (int k = 0; k < n; k++) {
        const rd_select_stats *t = &st[m * k];
        double lit = 0.0;
        for (int e = 0; e < m; e++) lit += t[e].nonzero, num[m * k + e] = den[m * k + e] = 0.0;
        if (!(lit > 0.0)) continue;
        for (int c = 0; c < 3; c++) {
            double mu = tile_mean(t, m, c, centre);
            for (int e = 0; e < m; e++)
                if (t[e].dof > 0.0) num[m * k + e] += t[e].dev2[c], den[m * k + e] += t[e].dof * mu * mu;
        }
        for (int e = 0; e < m; e++) N[e] += num[m * k + e], D[e] += den[m * k + e];
    }
    int nx = sel->tiles_x, ny = sel->tiles_y;
    for (int k = 0; k < n; k++) {
        int tx = k % nx, ty = k / nx;
        double a[RD_SEL_MAX] = {0}, b[RD_SEL_MAX] = {0};
        for (int y = ty - 1; y <= ty + 1; y++) /* the 3x3 tiles k's figures are pooled over */
            for (int x = tx - 1; x <= tx + 1; x++) {
                if (x < 0 || y < 0 || x >= nx || y >= ny) continue;
                for (int e = 0; e < m; e++) a[e] += num[m * (y * nx + x) + e], b[e] += den[m * (y * nx + x) + e];
            }
        for (int e = 0; e < m; e++) {
            double d = D[e] - b[e];
            r[m * k + e] = d > 0.0 ? fmax(0.0, N[e] - a[e]) / d : 0.0;
        }
    }
}

/* The image's ratio of the beams' squared bias to their variance a sample (see the head, "The
 * beams' bias"), less SEL_BIAS_SIGMA standard errors and not below 0; *raw and *se the ratio
 * before the margin and its standard error (all 0 without the beams' products in at least
 * SEL_BIAS_TILES tiles). RD_SELECT_BIAS_PER_GAP2 times the weighted mean over the pixels of the
 * products of their odd and even passes' mean gaps (statistics st over all tiles: bias_fold),
 * times r2, the radius's square now over pass 1's (the gaps are read at pass 1's radius), over
 * the same weighted mean of their tiles' variance a sample (tile_variance's sample variance,
 * unbounded). The standard error is the noise's alone: each tile's sum D_k of its pixels'
 * products with two signs turned (bias_split), which where the gap is 0 have the products' own
 * variance and have mean 0 whatever the bias, each tile one draw (the pixels of a tile share the
 * photons of its passes, so their noise is shared): sqrt(sum_k D_k^2) over the weights' sum. It
 * reads low where a pixel's gap is large against its noise (D lacks the products' terms in the
 * gap times the noise), where the bias then shows many standard errors over. The bias's own
 * spread over the tiles is not noise and does not count. Neighbouring tiles share photons too
 * (a ball reaches across a tile's edge), so the variance of the sum takes their covariances,
 * 2 D_k D_j for each pair of tiles k, j that touch (8-neighbours, weight 1: a truncated
 * uniform kernel, which assumes a ball's footprint on the screen under one tile, else it still
 * reads low), their sum clamped at 0. The clamp is a positive part, not a bound: D_k is the
 * product of an even-class difference and an odd-class one, independent and alike, so
 * Cov(D_k, D_j) is the product of two nearly equal covariances, >= 0; a negative sum is noise
 * (from few tiles the cross terms are noisy: SEL_BIAS_TILES is 8). */
static double bias_ratio(const rd_select *sel, const rd_select_stats *st, double r2, double *raw, double *se_out)
{
    *raw = *se_out = 0.0;
    int n = sel->tiles_x * sel->tiles_y, m = sel->n;
    const int b = bound_centre(sel);
    if (b < 0) return 0.0;
    const int nx = sel->tiles_x, ny = sel->tiles_y;
    double sum = 0.0, weight = 0.0, v = 0.0, tiles = 0.0, d2 = 0.0, cross = 0.0;
    for (int k = 0; k < n; k++) {
        const rd_select_stats *a = &st[m * k + b];
        if (!(a->bias_n > 0.0 && a->dof > 0.0)) continue;
        sum += a->bias2, weight += a->bias_n, tiles += 1.0, d2 += a->bias_split * a->bias_split;
        v += a->bias_n * (a->dev2[0] + a->dev2[1] + a->dev2[2]) / (3.0 * a->dof);
        /* each touching pair once: the neighbours to the right and in the row below */
        static const int step[4][2] = {{1, 0}, {-1, 1}, {0, 1}, {1, 1}};
        for (int i = 0; i < 4; i++) {
            int x = k % nx + step[i][0], y = k / nx + step[i][1];
            if (x < 0 || x >= nx || y >= ny) continue;
            const rd_select_stats *o = &st[m * (y * nx + x) + b];
            if (o->bias_n > 0.0 && o->dof > 0.0) cross += a->bias_split * o->bias_split;
        }
    }
    if (!(tiles >= SEL_BIAS_TILES && v > 0.0)) return 0.0;
    const double mean = sum / weight, se = sqrt(d2 + fmax(0.0, 2.0 * cross)) / weight;
    const double scale = RD_SELECT_BIAS_PER_GAP2 * r2 / (v / weight);
    if (!isfinite(mean * scale) || !isfinite(se * scale)) return 0.0;
    *raw = mean * scale, *se_out = se * scale;
    return fmax(0.0, (mean - SEL_BIAS_SIGMA * se) * scale);
}

/* The beams' squared bias in each tile, bias[m k + b] for the beams estimator b (the others
 * 0), as a sum over the tile's pixels (see the head, "The beams' bias"): the image's ratio
 * (bias_ratio) times the beams' variance figure var[m k + b] (figures()), times the factor by
 * which the tile's past beams samples add to the bias of its mean (statistics st). */
static void bias_figures(const rd_select *sel, const rd_select_stats *st, const double *var, const rd_select_past *past,
                         double ratio, double *bias)
{
    int n = sel->tiles_x * sel->tiles_y, m = sel->n;
    memset(bias, 0, (size_t)m * n * sizeof *bias);
    const int b = bound_centre(sel);
    if (b < 0 || !(ratio > 0.0)) return;
    for (int k = 0; k < n; k++) {
        /* the tile's past beams samples, a share s of its image samples, carry the same bias:
         * beams to come add a^2 (1 + 2 n0 s / a) B to the squared bias of the mean's sum */
        double held = 0.0;
        for (int e = 0; e < m; e++) held += st[m * k + e].image_n;
        const double share = held > 0.0 ? st[m * k + b].image_n / held : 0.0;
        double grow = 1.0;
        if (past && past->left > 0.0) grow += 2.0 * past->n0 * share / past->left;
        else if (past && past->R > 0.0) grow += 2.0 * share * past->T0 / past->R; /* (a = ahead n0) */
        bias[m * k + b] = ratio * grow * var[m * k + b];
    }
}

/* Of delta's paths (sel->paths), the one the rule picks for the image as one tile: the least
 * V C, with the samples all[m k + e] summed over the lit tiles and each estimator's non-zero
 * prior pbar[e] (see the head, "Tiles no sample has lit"). */
static int image_path(const rd_select *sel, const rd_select_stats *all, const double *pbar)
{
    const int centre = bound_centre(sel);
    int n = sel->tiles_x * sel->tiles_y, m = sel->n;
    rd_select_stats sum[RD_SEL_MAX];
    memset(sum, 0, sizeof sum);
    for (int k = 0; k < n; k++) {
        const rd_select_stats *st = &all[m * k];
        double lit = 0.0;
        for (int e = 0; e < m; e++) lit += st[e].nonzero;
        if (!(lit > 0.0)) continue;
        for (int e = 0; e < m; e++) {
            rd_select_stats *t = &sum[e];
            t->n += st[e].n, t->nonzero += st[e].nonzero, t->dof += st[e].dof, t->cost += st[e].cost;
            for (int c = 0; c < 3; c++) t->sum[c] += st[e].sum[c], t->dev2[c] += st[e].dev2[c];
        }
    }
    int best = RD_SEL_DELTA;
    double fbest = 0.0;
    for (int e = 0; e < m; e++) {
        if (!(sel->paths >> e & 1u) || !(sum[e].n > 0.0)) continue;
        double f = tile_variance(sum, m, e, pbar[e], 0.0, centre) * sum[e].cost / sum[e].n;
        if (e == RD_SEL_DELTA || f < fbest * (1.0 - SEL_TIE)) best = e, fbest = f;
    }
    return best;
}

/* Choose every tile's estimator from the statistics so far: the rule on each half of the
 * samples alone, the estimator both halves want, or else the rule's on the image's predicted
 * variances if it is one of their two, else the cheaper of their two (see the head, "Replication"
 * and "Where the halves disagree"); a move to the estimator with far fewer samples, or one the
 * halves disagree on, goes on trial first ("Evidence of unequal size"), but a tile no sample has
 * lit ("Tiles no sample has lit") and one leaving the beams while their bias is read ("Off the
 * biased beams at once") move at once. */
void rd_select_choose_tiles(rd_select *sel, const rd_select_end *end)
{
    int nx = sel->tiles_x, ny = sel->tiles_y, n = nx * ny, m = sel->n;
    size_t mn = (size_t)m * n;
    rd_select_stats *all = malloc(mn * sizeof *all);
    double *buf = malloc(8 * mn * sizeof *buf);
    uint8_t *want = malloc(3 * (size_t)n); /* the two halves', and the image's (image_want) */
    if (!all || !buf || !want) { /* the choices stay as they are */
        free(all), free(buf), free(want);
        return;
    }
    double *var = buf, *cost = buf + mn, *all_cost = buf + 2 * mn, *tmp = buf + 3 * mn, *r = buf + 4 * mn;
    double *bias = buf + 7 * mn;
    const rd_select_stats *half[2] = {sel->stats, sel->stats + mn};
    for (size_t i = 0; i < mn; i++) { /* a tile's samples: its two halves' */
        const rd_select_stats *a = &half[0][i], *b = &half[1][i];
        rd_select_stats *t = &all[i];
        t->n = a->n + b->n, t->nonzero = a->nonzero + b->nonzero, t->dof = a->dof + b->dof;
        t->cost = a->cost + b->cost;
        t->image_n = a->image_n + b->image_n, t->image_cost = a->image_cost + b->image_cost;
        for (int c = 0; c < 3; c++) t->sum[c] = a->sum[c] + b->sum[c], t->dev2[c] = a->dev2[c] + b->dev2[c];
        t->gap = a->gap + b->gap, t->bias2 = a->bias2 + b->bias2, t->bias_n = a->bias_n + b->bias_n;
        t->bias_split = a->bias_split + b->bias_split;
    }

    /* Each estimator's non-zero fraction over the lit tiles: the prior of every tile's p. */
    double nz[RD_SEL_MAX] = {0}, nn[RD_SEL_MAX] = {0}, pbar[RD_SEL_MAX];
    for (int k = 0; k < n; k++) {
        const rd_select_stats *st = &all[m * k];
        double lit = 0.0;
        for (int e = 0; e < m; e++) lit += st[e].nonzero;
        if (!(lit > 0.0)) continue;
        for (int e = 0; e < m; e++) nz[e] += st[e].nonzero, nn[e] += st[e].n;
    }
    for (int e = 0; e < m; e++) pbar[e] = (nz[e] + 1.0) / (nn[e] + 2.0);
    if (sel->unlit < 0) sel->unlit = image_path(sel, all, pbar); /* the pilot's samples */
    int two_paths = (sel->paths & (sel->paths - 1u)) != 0u;
    /* the beams' bias ratio, one for the image (the gaps are at pass 1's radius: r^2 now) */
    const double rs = end && end->radius_scale > 0.0 ? end->radius_scale : 1.0;
    sel->bias_r2 = rs * rs;
    const double ratio = bias_ratio(sel, all, sel->bias_r2, &sel->bias_ratio, &sel->bias_se);
    rd_select_past past;
    for (int h = 0; h < 2; h++) {
        figures(sel, half[h], pbar, NULL, var, cost, tmp);
        const rd_select_past *p = past_of(sel, all, var, end, &past) ? &past : NULL;
        bias_figures(sel, all, var, p, ratio, bias); /* (the image's ratio, on each half's variance) */
        choose(sel, var, cost, bias, p, want + (size_t)h * n);
    }
    figures(sel, all, pbar, NULL, NULL, all_cost, tmp);
    /* What the tiles beyond a tile's pooling predict, for the tiles whose halves disagree (see
     * the head); a tile for which any estimator has no prediction (r 0: no deviation of its
     * samples beyond the 3x3 tiles) has no such choice (RD_SEL_MAX), and a split goes to the
     * cheaper of the two. */
    uint8_t *image_want = want + 2 * (size_t)n;
    pooled_relative_variance(sel, all, r, r + mn, r + 2 * mn);
    figures(sel, all, pbar, r, var, cost, tmp);
    const rd_select_past *p = past_of(sel, all, var, end, &past) ? &past : NULL;
    bias_figures(sel, all, var, p, ratio, bias);
    choose(sel, var, cost, bias, p, image_want);
    for (int k = 0; k < n; k++)
        for (int e = 0; e < m; e++)
            if (!(r[m * k + e] > 0.0)) image_want[k] = RD_SEL_MAX;
    /* The evidence is the tile's own samples (its neighbours, committed to one estimator,
     * would outweigh its trial in a pooled count for ever). A trial lasts one epoch: then the
     * rule decides. */
    for (int k = 0; k < n; k++) {
        int a = want[k], b = want[n + k], w = a;
        double na = 0.0, nb = 0.0, ca = all_cost[m * k + a], cb = all_cost[m * k + b];
        for (int e = 0; e < m; e++) na += half[0][m * k + e].n, nb += half[1][m * k + e].n;
        int split = a != b && na > 0.0 && nb > 0.0; /* they differ and both have samples */
        if (split) /* the image's choice between the two, or else the cheaper of them */
            w = image_want[k] == a || image_want[k] == b ? image_want[k] : ca < cb || (ca == cb && a < b) ? a : b;
        else if (!(na > 0.0)) w = b;
        int cur = sel->choice[k];
        const rd_select_stats *st = &all[m * k];
        double lit = 0.0;
        for (int e = 0; e < m; e++) lit += st[e].nonzero;
        if (two_paths && !(lit > 0.0) && w == RD_SEL_DELTA) { /* no evidence to weigh: no trial */
            sel->choice[k] = (uint8_t)sel->unlit;
            sel->trial[k] = 0;
            continue;
        }
        /* after a trial, only the estimator on trial is taken without the ratio's test: with
         * three, the rule may want the one that was not on trial, on its pilot's samples alone;
         * a move the halves do not agree on goes on trial first, but off the biased beams */
        int on_trial = sel->trial[k] && w == sel->trial[k] - 1;
        /* off the beams while the image reads their bias: at once (the head, "Off the biased
         * beams at once") */
        int off_biased = ratio > 0.0 && p && cur == bound_centre(sel) && w != cur;
        if (w == cur || on_trial || off_biased || (!split && st[w].n * RD_SELECT_TRIAL_RATIO >= st[cur].n)) {
            sel->choice[k] = (uint8_t)w; /* the same, after its trial, on comparable evidence, or
                                            off the biased beams */
            sel->trial[k] = 0;
        } else {
            sel->trial[k] = (uint8_t)(1 + w); /* lopsided evidence, or halves that differ: half
                                                 the pixels try w for an epoch */
        }
    }
    /* the shares of the samples and their weights, from all the tile's samples (select_share.c;
     * "pilot"'s, without weights or blocks, at the pilot's choice alone: no figures for the epochs') */
    if (sel->share && (sel->weight || sel->blocks || sel->choices == 0)) {
        figures(sel, all, pbar, NULL, var, cost, tmp);
        rd_select_set_shares(sel, all, var, cost);
    }
    free(all), free(buf), free(want);
}
