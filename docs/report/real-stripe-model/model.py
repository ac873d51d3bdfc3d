#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Offline model of the gray method's default rule and of the stripe-averaged
margin rule (docs/report/real.md, "Averaging along the stripe, and an
image-level gate"). Not part of the build: numpy, scipy and PIL (Debian:
python3-numpy python3-scipy python3-pil). Used by run.py beside it.

Model of the rule (decode.hpp): lit = W - B >= 0.03 * 255, thr = max(0.1 C,
K sigma_d) with sigma_d^2 = a + b (W + B) fitted from the pair sums' spread,
finest plane tolerated, <= 3 uncertain strict planes enumerated, no ties,
candidates without a gap and half-width <= 1.5. Planes most significant first.
"""
import numpy as np, sys, json
from PIL import Image
import os
# The real sample is not in the repository: point PROCAM_DATA_DIR at the
# folder that holds real/procam-calibration-sample/ (docs/report/real.md).
if not os.environ.get('PROCAM_DATA_DIR'):
    sys.exit('model.py: set PROCAM_DATA_DIR to the folder holding real/procam-calibration-sample/ '
             '(the procam-calibration sample, MIT; see docs/report/real.md)')
S=os.path.join(os.environ['PROCAM_DATA_DIR'],
             'real/procam-calibration-sample/sample_data/capture_%d/graycode_%02d.png')
def load(c):
    return np.stack([np.asarray(Image.open(S%(c,i)).convert('L'),dtype=np.float32) for i in range(42)])
def noisefit(F):
    W,B=F[40],F[41]; Ssum=W+B
    sums=np.stack([F[2*k]+F[2*k+1] for k in range(20)])
    var=sums.var(0,ddof=1); m=sums.mean(0)
    # binned robust fit: median var per bin of mean
    bins=np.arange(0,512,8); idx=np.digitize(m.ravel(),bins)
    xs=[];ys=[]
    for i in np.unique(idx):
        sel=idx==i
        if sel.sum()<200: continue
        xs.append(m.ravel()[sel].mean()); ys.append(np.median(var.ravel()[sel]))
    A=np.vstack([np.ones(len(xs)),xs]).T
    a,b=np.linalg.lstsq(A,np.array(ys),rcond=None)[0]
    return max(a,0),b
from scipy import ndimage as ndi
K=3.0
def gray2bin(g):
    b=g.copy()
    s=1
    while s<16:
        b^=b>>s; s<<=1
    return b
def prep(F,ab,W=None,B=None,pairs=None):
    a,b=ab
    if W is None:
        W,B=F[40],F[41]; pairs=[(F[2*k],F[2*k+1]) for k in range(10)]
    C=W-B
    d=np.stack([p[0]-p[1] for p in pairs])
    sig=np.sqrt(a+b*(W+B))
    thr=np.maximum(0.1*C, K*sig)
    lit=C>=0.03*255
    sat=np.zeros_like(lit)
    for p in pairs: sat|=(p[0]>=255)&(p[1]>=255)
    return dict(W=W,B=B,C=C,d=d,sig=sig,thr=thr,lit=lit&~sat)
def decode(P, d=None, certain_override=None, maxhalf=1.5, ncols=1024):
    """Model of gray's default rule. d: margins (10,H,W). certain_override: bool (10,H,W) planes forced certain.
    returns col (nan invalid), unc"""
    if d is None: d=P['d']
    thr=P['thr']; lit=P['lit']
    nb=d.shape[0]
    unc=np.abs(d)<=thr
    if certain_override is not None: unc&=~certain_override
    tie=(d==0)&unc
    bits=(d>0).astype(np.int32)
    g=np.zeros(d.shape[1:],np.int32)
    for k in range(nb): g=(g<<1)|bits[k]
    nU=unc[:nb-1].sum(0)
    ok=lit&~tie.any(0)&(nU<=3)
    # enumerate candidates: for each pixel, list of uncertain planes (<=4)
    H,Wd=g.shape
    col=np.full((H,Wd),np.nan,np.float32); uc=np.full((H,Wd),np.nan,np.float32)
    # certain pixels
    nun=unc.sum(0)
    cert=ok&(nun==0)&(gray2bin(g)<ncols)
    col[cert]=gray2bin(g[cert]); uc[cert]=0
    # uncertain ones
    idx=np.nonzero(ok&(nun>0))
    gu=g[idx]; U=unc[:,idx[0],idx[1]]  # (10,n)
    n=gu.size
    masks=[]
    # candidate words: subsets of set bits of mask M
    M=np.zeros(n,np.int32)
    for m in masks: M|=m
    # enumerate subsets by iterating over 16 combos of up to 4 bits
    bitlist=np.zeros((4,n),np.int32); cnt=np.zeros(n,np.int32)
    for k in range(nb):
        has=U[k]
        for j in range(4):
            put=has&(cnt==j)
            bitlist[j][put]=1<<(nb-1-k)
        cnt+=has
    lo=np.full(n,1e9); hi=np.full(n,-1e9); allc=[]
    for s in range(16):
        w=gu.copy()
        for j in range(4):
            if s>>j&1: w^=bitlist[j]
        c=gray2bin(w); allc.append(c)
    allc=np.stack(allc)  # duplicates when fewer bits: fine
    lo=allc.min(0); hi=allc.max(0)
    # no gap: number of distinct columns == hi-lo+1
    srt=np.sort(allc,0); distinct=1+(np.diff(srt,axis=0)>0).sum(0)
    good=(distinct==hi-lo+1)&((hi-lo)/2<=maxhalf)&(hi<ncols)
    col[idx[0][good],idx[1][good]]=(lo[good]+hi[good])/2
    uc[idx[0][good],idx[1][good]]=(hi[good]-lo[good])/2
    return col,uc
def plain(P,reject_ties=True):
    d=P['d']; lit=(P['C']>=20)
    bits=(d>0).astype(np.int32)
    g=np.zeros(d.shape[1:],np.int32)
    for k in range(10): g=(g<<1)|bits[k]
    col=gray2bin(g).astype(np.float32)
    keep=lit.copy()
    if reject_ties: keep&=~(d==0).any(0)
    col[~keep]=np.nan
    return col
def outliers(col):
    c=col[:,1:-1]; l=col[:,:-2]; r=col[:,2:]
    return int(np.sum(~np.isnan(c)&~np.isnan(l)&~np.isnan(r)&(np.abs(c-l)>3)&(np.abs(c-r)>3)))
def coverage(col,ref):
    return np.sum(~np.isnan(col)&~np.isnan(ref))/np.sum(~np.isnan(ref))
def orientation(P, sigma=3.0, planes=(3,4,5,6,7)):
    C=np.maximum(P['C'],1)
    Jxx=0;Jxy=0;Jyy=0
    for k in planes:
        v=P['d'][k]/C
        gy,gx=np.gradient(ndi.gaussian_filter(v,1.0))
        Jxx=Jxx+gx*gx; Jxy=Jxy+gx*gy; Jyy=Jyy+gy*gy
    Jxx=ndi.gaussian_filter(Jxx,sigma);Jxy=ndi.gaussian_filter(Jxy,sigma);Jyy=ndi.gaussian_filter(Jyy,sigma)
    # gradient direction angle phi = 0.5 atan2(2Jxy, Jxx-Jyy); stripe tangent = phi+90deg
    phi=0.5*np.arctan2(2*Jxy,Jxx-Jyy)
    tx=-np.sin(phi); ty=np.cos(phi)
    coh=np.sqrt((Jxx-Jyy)**2+4*Jxy**2)/(Jxx+Jyy+1e-12)
    return tx,ty,coh
def along(img, tx, ty, h, valid=None):
    """mean of img over offsets j=-h..h along (tx,ty), nearest sampling; also count of valid samples"""
    H,Wd=img.shape[-2:]
    yy,xx=np.mgrid[0:H,0:Wd]
    acc=np.zeros(img.shape,np.float64); n=np.zeros((H,Wd),np.int32)
    allok=np.ones((H,Wd),bool)
    for j in range(-h,h+1):
        xs=np.rint(xx+j*tx).astype(np.int32); ys=np.rint(yy+j*ty).astype(np.int32)
        inb=(xs>=0)&(xs<Wd)&(ys>=0)&(ys<H)
        xs=np.clip(xs,0,Wd-1); ys=np.clip(ys,0,H-1)
        ok=inb if valid is None else inb&valid[ys,xs]
        allok&=ok
        acc+=np.where(ok,img[...,ys,xs],0); n+=ok
    return acc/np.maximum(n,1), n, allok
def fit_pairs(m, var, sel):
    bins=np.arange(0,512,8); idx=np.digitize(m[sel],bins); xs=[];ys=[]
    for i in np.unique(idx):
        s=idx==i
        if s.sum()<200: continue
        xs.append(m[sel][s].mean()); ys.append(np.median(var[sel][s]))
    A=np.vstack([np.ones(len(xs)),xs]).T; aa,bb=np.linalg.lstsq(A,np.array(ys),rcond=None)[0]
    return max(aa,0),bb
def stripe_rule(P, sums, h, with_c=False, tdir=None, gate=0):
    """returns d', override: uncertain planes decided by the margin averaged over 2h+1 pixels along the stripe"""
    lit=P['lit']
    tx,ty,coh=orientation(P) if tdir is None else tdir
    davg,n,allok=along(P['d'],tx,ty,h,valid=lit)
    savg,_,_=along(sums,tx,ty,h,valid=lit)
    aa,bb=fit_pairs(savg.mean(0),savg.var(0,ddof=1),allok&lit)
    sig_avg=np.sqrt(np.maximum(aa+bb*(P['W']+P['B']),1e-6))
    thrA=K*sig_avg
    if with_c: thrA=np.maximum(thrA,0.1*P['C'])
    unc=np.abs(P['d'])<=P['thr']
    ov=unc&(np.abs(davg)>thrA)&allok
    if gate==1: ov&=(K*P['sig']>=0.1*P['C'])[None]
    return np.where(ov,davg,P['d']), ov, (aa,bb)
